//! Configuration of the simulated rig (the `[sim]` table of a rig TOML file).

use crate::truth::{
    CameraIntrinsics, CameraPose, LampCircle, LampTruth, Point3, SensorTruth, SphereGeometry,
};
use serde::{Deserialize, Serialize};

/// Probabilities of injected faults; each is rolled once per operation of the device it
/// concerns, from a seeded generator, so a run with the same seed fails in the same places.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct FaultConfig {
    /// Seed of the fault generators (independent of the noise seed).
    pub seed: u64,
    /// Per move: the turntable stalls and the move times out.
    pub turntable_timeout: f64,
    /// Per move: the stepper loses steps; the position is lost until homed again.
    pub turntable_lost_steps: f64,
    /// Per capture: the frame never arrives.
    pub camera_frame_drop: f64,
    /// Per capture: the camera disconnects (until reconnected).
    pub camera_disconnect: f64,
    /// Per capture: the frame arrives with corrupted data.
    pub camera_corrupted_frame: f64,
    /// Per capture: the lamp goes dark.
    pub lamp_dropout: f64,
    /// Per capture: the lamp output jumps.
    pub lamp_flicker: f64,
    /// Relative size of a flicker jump (the sign is random).
    pub lamp_flicker_magnitude: f64,
}

impl Default for FaultConfig {
    fn default() -> Self {
        Self {
            seed: 0,
            turntable_timeout: 0.0,
            turntable_lost_steps: 0.0,
            camera_frame_drop: 0.0,
            camera_disconnect: 0.0,
            camera_corrupted_frame: 0.0,
            lamp_dropout: 0.0,
            lamp_flicker: 0.0,
            lamp_flicker_magnitude: 0.05,
        }
    }
}

/// Mechanical and timing parameters of the simulated devices.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct TimingConfig {
    /// Sensor readout and transfer time per frame, seconds.
    pub readout_s: f64,
    /// Turntable speed, degrees per second.
    pub turntable_speed_deg_per_s: f64,
    /// Settling time after each move, seconds.
    pub settle_s: f64,
    /// Extra time of a homing cycle, seconds.
    pub homing_overhead_s: f64,
}

impl Default for TimingConfig {
    fn default() -> Self {
        Self {
            readout_s: 0.35,
            turntable_speed_deg_per_s: 2.0,
            settle_s: 1.0,
            homing_overhead_s: 5.0,
        }
    }
}

/// All settings of the simulated rig. Defaults describe the thesis's gantry at full resolution
/// (1300 × 1030, 1-inch-radius sphere 1 m from the camera, lamp 0.5 m from the sphere).
///
/// # Examples
///
/// The `[sim]` table of a rig file (`docs/rig.example.toml` lists every key); keys left out keep
/// their defaults:
///
/// ```
/// use gantry_hal::RigConfig;
/// use hal_sim::{SimConfig, SimRig};
///
/// let file = RigConfig::from_toml_str(r#"
///     backend = "sim"
///     [sim]
///     seed = 7
///     scale = 0.1
///     material = "ggx:alpha=0.2,kd=0.1"
/// "#).unwrap();
/// let config = SimConfig::from_table(file.sim.as_ref().unwrap()).unwrap();
/// assert_eq!((config.seed, config.scale), (7, 0.1));
/// assert_eq!(config.sphere, SimConfig::default().sphere);
/// let sim = SimRig::from_rig_config(&file).unwrap();
/// assert_eq!(sim.scene().width(), 130);
/// ```
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct SimConfig {
    /// Seed of all noise and fixed-pattern maps.
    pub seed: u64,
    /// Sensor scale factor (1 = 1300 × 1030; 0.1 = 130 × 103 with the same field of view).
    pub scale: f64,
    /// Material spec (see `brdf::spec`), used when the rig is built from configuration.
    pub material: String,
    /// Full-resolution camera intrinsics.
    pub camera: CameraIntrinsics,
    /// Camera centre, world metres.
    pub camera_centre: Point3,
    /// Point the camera looks at.
    pub camera_target: Point3,
    /// Roll about the optical axis, degrees.
    pub camera_roll_deg: f64,
    /// The sample sphere.
    pub sphere: SphereGeometry,
    /// The lamp.
    pub lamp: LampTruth,
    /// Sensor parameters.
    pub sensor: SensorTruth,
    /// Stray-light radiance floor per channel, W m⁻² sr⁻¹.
    pub stray_radiance: [f64; 3],
    /// Device timing.
    pub timing: TimingConfig,
    /// Fault injection.
    pub faults: FaultConfig,
    /// Shortest exposure of the camera, seconds.
    pub min_exposure_s: f64,
    /// Longest exposure of the camera, seconds.
    pub max_exposure_s: f64,
}

impl Default for SimConfig {
    fn default() -> Self {
        let normal = [0.0, 0.0, 1.0];
        Self {
            seed: 1,
            scale: 1.0,
            material: "lambert:kd=0.5".into(),
            camera: CameraIntrinsics {
                width: 1300,
                height: 1030,
                fx: 12_150.0,
                fy: 12_170.0,
                cx: 652.4,
                cy: 511.8,
                k1: -0.35,
                k2: 0.8,
                p1: 0.0,
                p2: 0.0,
                k3: 0.0,
            },
            camera_centre: [0.004, -1.0, 0.006],
            camera_target: [0.0, 0.0, 0.0],
            camera_roll_deg: 0.4,
            sphere: SphereGeometry {
                centre: [0.0005, -0.0003, 0.0002],
                radius: 0.0254,
            },
            lamp: LampTruth {
                circle: LampCircle {
                    centre: [0.0012, 0.0008, -0.0015],
                    normal,
                    radius: 0.5,
                    reference: [0.0, 1.0, 0.0],
                },
                disc_radius: 0.01,
                radiant_intensity: [1.0, 1.1, 0.9],
                warm_up_s: 600.0,
            },
            sensor: SensorTruth::default(),
            stray_radiance: [2e-4, 2e-4, 2e-4],
            timing: TimingConfig::default(),
            faults: FaultConfig::default(),
            min_exposure_s: 40e-6,
            max_exposure_s: 60.0,
        }
    }
}

impl SimConfig {
    /// The default rig at sensor scale `scale`.
    pub fn with_scale(scale: f64) -> Self {
        Self {
            scale,
            ..Self::default()
        }
    }

    /// Parses the `[sim]` table of a rig configuration.
    pub fn from_table(table: &toml::Table) -> Result<Self, crate::SimError> {
        table
            .clone()
            .try_into()
            .map_err(|e: toml::de::Error| crate::SimError::Config(e.to_string()))
    }

    /// The world-to-camera pose.
    pub fn pose(&self) -> CameraPose {
        CameraPose::look_at(
            self.camera_centre,
            self.camera_target,
            self.camera_roll_deg.to_radians(),
        )
    }
}
