//! # hal-sim — the physically simulated measurement gantry
//!
//! ```
//! use gantry_hal::Rig;
//! use hal_sim::{SimConfig, SimRig};
//! use std::sync::Arc;
//! use std::time::Duration;
//!
//! // the simulated rig at a tenth of the sensor resolution, with a GGX sphere
//! let material = brdf::load("ggx:alpha=0.2,kd=0.2").unwrap();
//! let mut config = SimConfig::with_scale(0.1);
//! config.lamp.warm_up_s = 0.0;
//! let sim = SimRig::new(config, Arc::new(material)).unwrap();
//! let Rig { mut turntable, mut lamp, mut camera, .. } = sim.rig();
//! let wait = Duration::from_secs(600);
//! turntable.home(wait).unwrap();
//! turntable.move_to(90.0, wait).unwrap();
//! camera.set_exposure(0.2).unwrap();
//! let unlit = camera.capture(wait).unwrap();
//! lamp.set_on(true).unwrap();
//! let lit = camera.capture(wait).unwrap();
//! assert_eq!(lit.bit_depth, 10);
//! // the lamp lights the sphere: the frame collects far more signal than with the lamp off
//! // the lamp lights the sphere: many photosites well above the dark level, none without it
//! let bright = |f: &gantry_hal::BayerFrame| f.data.iter().filter(|&&v| v > 100).count();
//! assert!(bright(&lit) > 50 && bright(&unlit) < 5, "{} {}", bright(&lit), bright(&unlit));
//! ```
//!
//! A seeded, deterministic stand-in for the gantry of thesis §3.1 that implements the
//! `gantry-hal` device traits, so that the capture (thesis §3.3–3.6) and the calibration
//! (thesis §3.2) run in CI, and a capture's result can be compared with the truth.
//!
//! * [`SimConfig`] describes the rig (the `[sim]` table of a rig file): a matte-black room with a
//!   stray-light floor, a sphere of any [`brdf::Brdf`], a pinhole camera with radial distortion,
//!   a small lamp disc on a circle driven by the turntable, an RGGB sensor with shot, read and
//!   dark noise, PRNU, hot pixels, gain, black level, 10-bit quantisation and saturation, the
//!   device timings, and the faults to inject ([`FaultConfig`]).
//! * [`SimRig`] builds it. [`SimRig::rig`] hands out turntable, lamp and camera as a
//!   [`gantry_hal::Rig`] on a simulated clock; beside them the ground truth stays available:
//!   [`SceneTruth`] (geometry, lamp, sensor), [`PositionTruth`] (the noise-free signal of every
//!   photosite at a lamp angle) and the hot pixels.
//! * [`Scene`] is the renderer and sensor model behind the devices.
//! * For calibration (thesis §3.2): [`Checkerboard`] targets in chosen [`TargetPose`]s, captured
//!   through the same sensor ([`SimRig::capture_checkerboard_frames`]), and a
//!   [`ContactDigitizer`] that returns noisy 3-D points of the lamp, the sphere and the
//!   digitizer tip.
//! * With feature `grbl-emulator` (on by default; the workspace dependency turns it off),
//!   `GrblEmulator` is a GRBL 1.1 controller on a pseudo-terminal, with a `HostileLink` that
//!   injects faults, for testing the real serial driver of `gantry-hal`.
//!
//! Noise comes from a counter-based generator keyed by (seed, frame number, pixel)
//! ([`PixelStream`]), so frames are bit-identical for the same seed whatever the thread count.

#![warn(missing_docs)]

mod calibration;
mod config;
mod devices;
#[cfg(feature = "grbl-emulator")]
mod grbl_emulator;
mod rng;
mod scene;
mod truth;

#[cfg(feature = "grbl-emulator")]
pub use grbl_emulator::{
    EmulatorFaults, GrblEmulator, GrblEmulatorConfig, HostileLink, InjectedFaults,
};
pub use rng::{frame_key, PixelStream, POISSON_EXACT_BELOW};
pub use truth::{LampTruth, Point3, SensorTruth};

pub use calibration::{
    Checkerboard, CheckerboardCapture, ContactDigitizer, TargetPose, TipObservation,
};
pub use config::{FaultConfig, SimConfig, TimingConfig};
pub use scene::{PositionTruth, Scene};
pub use truth::{CameraIntrinsics, CameraPose, LampCircle, SceneTruth, SphereGeometry};

use devices::{SimCamera, SimLamp, SimTurntable, World};
use gantry_hal::{Rig, SimulatedClock};
use std::sync::Arc;

/// Errors of the simulator.
#[derive(Debug, thiserror::Error)]
pub enum SimError {
    /// The simulation configuration is invalid.
    #[error("simulation configuration: {0}")]
    Config(String),
    /// Buffers of the wrong size.
    #[error("dimension mismatch: {0}")]
    Dimensions(String),
    /// The material could not be loaded.
    #[error("material: {0}")]
    Material(String),
    /// A device-level error.
    #[error(transparent)]
    Hal(#[from] gantry_hal::HalError),
    /// I/O error (emulator link).
    #[error("I/O: {0}")]
    Io(#[from] std::io::Error),
}

/// The simulated rig: scene, shared device state and clock. [`SimRig::rig`] hands out the
/// devices as a `gantry_hal::Rig`; the ground-truth accessors stay available alongside.
///
/// # Examples
///
/// The crate documentation drives the devices; here the ground truth is asked directly. The
/// true geometry projects the sphere's centre onto a photosite that sees the sphere, and with
/// the lamp beside the camera that photosite collects far more signal than the black room
/// around the sphere:
///
/// ```
/// use hal_sim::{SimConfig, SimRig};
/// use nalgebra::Vector3;
/// use std::sync::Arc;
///
/// let material = brdf::load("ggx:alpha=0.2,kd=0.1").unwrap();
/// let sim = SimRig::new(SimConfig::with_scale(0.1), Arc::new(material)).unwrap();
/// let (w, h) = (sim.scene().width(), sim.scene().height());
/// assert_eq!((w, h), (130, 103)); // a tenth of the 1300 × 1030 sensor
///
/// let geometry = sim.truth().geometry();
/// let [u, v] = geometry.project(&Vector3::from(geometry.sphere.centre)).unwrap();
/// let centre = v.round() as usize * w + u.round() as usize;
/// let truth = sim.position_truth(180.0); // the lamp circle starts opposite the camera
/// assert!(truth.on_sphere[centre]);
/// assert!(!truth.on_sphere[0]);
/// let (sphere, room) = (truth.signal_rate_dn_per_s[centre], truth.signal_rate_dn_per_s[0]);
/// assert!(sphere > 100.0 * room, "{sphere} {room}");
/// ```
pub struct SimRig {
    world: Arc<World>,
}

impl std::fmt::Debug for SimRig {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("SimRig")
            .field("scene", &self.world.scene)
            .finish_non_exhaustive()
    }
}

fn check_probability(name: &str, p: f64) -> Result<(), SimError> {
    if (0.0..=1.0).contains(&p) {
        Ok(())
    } else {
        Err(SimError::Config(format!("fault probability {name} = {p}")))
    }
}

impl SimRig {
    /// Builds the simulated rig of `config` with the sample material `brdf`.
    pub fn new(config: SimConfig, brdf: Arc<dyn brdf::Brdf>) -> Result<Self, SimError> {
        let f = &config.faults;
        for (n, p) in [
            ("turntable_timeout", f.turntable_timeout),
            ("turntable_lost_steps", f.turntable_lost_steps),
            ("camera_frame_drop", f.camera_frame_drop),
            ("camera_disconnect", f.camera_disconnect),
            ("camera_corrupted_frame", f.camera_corrupted_frame),
            ("lamp_dropout", f.lamp_dropout),
            ("lamp_flicker", f.lamp_flicker),
        ] {
            check_probability(n, p)?;
        }
        let t = &config.timing;
        if !(t.turntable_speed_deg_per_s > 0.0 && t.readout_s >= 0.0 && t.settle_s >= 0.0) {
            return Err(SimError::Config("timing values must be positive".into()));
        }
        if !(config.min_exposure_s > 0.0 && config.max_exposure_s >= config.min_exposure_s) {
            return Err(SimError::Config("exposure range".into()));
        }
        let scene = Arc::new(Scene::new(&config, brdf)?);
        let clock = Arc::new(SimulatedClock::new());
        Ok(Self {
            world: Arc::new(World::new(scene, config, clock)),
        })
    }

    /// Builds the rig of `config`, loading its material spec with `brdf::load`.
    pub fn from_config(config: SimConfig) -> Result<Self, SimError> {
        let material =
            brdf::load(&config.material).map_err(|e| SimError::Material(e.to_string()))?;
        Self::new(config, Arc::new(material))
    }

    /// Builds the rig from the `[sim]` table of a rig configuration (defaults if absent).
    pub fn from_rig_config(cfg: &gantry_hal::RigConfig) -> Result<Self, SimError> {
        let sim = match &cfg.sim {
            Some(t) => SimConfig::from_table(t)?,
            None => SimConfig::default(),
        };
        Self::from_config(sim)
    }

    /// The devices of this rig. Several calls return handles onto the same devices.
    pub fn rig(&self) -> Rig {
        Rig {
            turntable: Box::new(SimTurntable {
                world: self.world.clone(),
            }),
            lamp: Box::new(SimLamp {
                world: self.world.clone(),
            }),
            camera: Box::new(SimCamera {
                world: self.world.clone(),
            }),
            clock: devices::as_clock(self.world.clock.clone()),
        }
    }

    /// The configuration the rig was built from.
    pub fn config(&self) -> &SimConfig {
        &self.world.config
    }

    /// The scene (renderer and sensor model).
    pub fn scene(&self) -> &Scene {
        &self.world.scene
    }

    /// Ground truth: geometry, lamp, sensor.
    pub fn truth(&self) -> &SceneTruth {
        self.world.scene.truth()
    }

    /// Noise-free per-pixel radiance and signal rate (DN/s) with the lamp at `angle_deg`.
    pub fn position_truth(&self, angle_deg: f64) -> PositionTruth {
        self.world.scene.position_truth(angle_deg)
    }

    /// Hot pixels (column, row): above 16 DN in a 60 s dark frame, noise-free.
    pub fn hot_pixels(&self) -> &[(usize, usize)] {
        self.world.scene.hot_pixels()
    }

    /// Starts a new, independently reproducible stretch of the capture (one lamp position): the
    /// fault streams and the frame numbers (which key the sensor noise) restart from `key`.
    /// A capture that calls this before each position gets the same frames for that position
    /// whether it ran straight through or was interrupted and resumed.
    pub fn begin_position(&self, key: u64) {
        let seed = self.world.config.faults.seed;
        self.world.lock().restart_streams(seed, key);
    }

    /// The simulated clock shared by the devices.
    pub fn clock(&self) -> Arc<SimulatedClock> {
        self.world.clock.clone()
    }

    /// Current turntable angle (ground truth, also when the turntable has lost its position).
    pub fn true_turntable_angle(&self) -> f64 {
        self.world.lock().angle_deg
    }

    /// Renders a checkerboard target at `pose` (target to camera) and captures it through the
    /// sensor model with exposure `exposure_s`. The lamp and sphere are not in this scene.
    pub fn capture_checkerboard(
        &self,
        board: &Checkerboard,
        pose: &TargetPose,
        exposure_s: f64,
    ) -> Result<CheckerboardCapture, SimError> {
        let mut caps = self.capture_checkerboard_frames(board, pose, exposure_s, 1)?;
        Ok(caps.remove(0))
    }

    /// `n` exposures of the checkerboard held still at `pose` (each with its own noise).
    pub fn capture_checkerboard_frames(
        &self,
        board: &Checkerboard,
        pose: &TargetPose,
        exposure_s: f64,
        n: usize,
    ) -> Result<Vec<CheckerboardCapture>, SimError> {
        calibration::check_board(board)?;
        let rgb = calibration::render_checkerboard(&self.world.scene, board, pose);
        let corners_px = calibration::true_corners(&self.world.scene, board, pose);
        self.expose_frames(&rgb, exposure_s, n)?
            .into_iter()
            .map(|frame| {
                Ok(CheckerboardCapture {
                    frame,
                    corners_px: corners_px.clone(),
                    pose: *pose,
                })
            })
            .collect()
    }

    /// `n` exposures of a diffuser in front of the lens, lit so that it has the uniform
    /// radiance `radiance` (W m⁻² sr⁻¹, every channel): flat-field frames, which show the
    /// photosites' own gains.
    pub fn capture_flat_frames(
        &self,
        radiance: f64,
        exposure_s: f64,
        n: usize,
    ) -> Result<Vec<gantry_hal::BayerFrame>, SimError> {
        if !(radiance >= 0.0 && radiance.is_finite()) {
            return Err(SimError::Config(format!("flat radiance {radiance}")));
        }
        let cam = self.truth().camera;
        let l = radiance as f32;
        let rgb = vec![[l; 3]; cam.width * cam.height];
        self.expose_frames(&rgb, exposure_s, n)
    }

    /// `n` exposures of the radiance image `rgb`, advancing the clock and the frame counter.
    fn expose_frames(
        &self,
        rgb: &[[f32; 3]],
        exposure_s: f64,
        n: usize,
    ) -> Result<Vec<gantry_hal::BayerFrame>, SimError> {
        (0..n)
            .map(|_| {
                let frame_number = {
                    let mut st = self.world.lock();
                    st.frame_counter += 1;
                    st.frame_counter
                };
                let frame = calibration::expose_radiance(
                    &self.world.scene,
                    rgb,
                    exposure_s,
                    self.world.clock.seconds(),
                    frame_number,
                )?;
                self.world.clock.advance(std::time::Duration::from_secs_f64(
                    exposure_s + self.world.config.timing.readout_s,
                ));
                Ok(frame)
            })
            .collect()
    }

    /// A contact digitizer measuring in the world frame with isotropic Gaussian noise of
    /// `sigma_m` metres, seeded by `seed`.
    pub fn digitizer(&self, sigma_m: f64, seed: u64) -> ContactDigitizer {
        ContactDigitizer::new(self.truth().clone(), sigma_m, seed)
    }
}
