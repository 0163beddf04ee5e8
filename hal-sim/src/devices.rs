//! Simulated turntable, lamp and camera sharing one world state and one simulated clock.

use crate::config::SimConfig;
use crate::scene::Scene;
use gantry_hal::{
    pack_bayer10, unpack_bayer10, Bayer10Format, BayerFrame, Camera, CameraInfo, Clock, DeviceKind,
    HalError, HalResult, Lamp, LampState, SimulatedClock, Turntable,
};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use std::sync::{Arc, Mutex, MutexGuard};
use std::time::Duration;

/// Relative output deficit of the lamp right after switching on; it decays linearly to zero over
/// the warm-up time.
pub const WARM_UP_DEFICIT: f64 = 0.1;

/// A lamp event waiting to be reported by [`Lamp::state`].
#[derive(Debug, Clone, Copy)]
enum LampEvent {
    Dropout { at_s: f64 },
    Flicker { change: f64, at_s: f64 },
}

/// Mutable state of the simulated world.
#[derive(Debug)]
pub(crate) struct WorldState {
    pub angle_deg: f64,
    pub homed: bool,
    pub speed: f64,
    pub lamp_on: bool,
    pub lamp_on_since: f64,
    /// Multiplier of the lamp output from faults (flicker); 1 nominal.
    pub lamp_fault_scale: f64,
    lamp_event: Option<LampEvent>,
    pub exposure_s: f64,
    pub frame_counter: u64,
    pub camera_connected: bool,
    cache_angle: Option<u64>,
    cache_rate: Arc<Vec<f32>>,
    stray_rate: Arc<Vec<f32>>,
    rng_turntable: ChaCha8Rng,
    rng_camera: ChaCha8Rng,
    rng_lamp: ChaCha8Rng,
}

/// What the simulated devices share.
pub(crate) struct World {
    pub scene: Arc<Scene>,
    pub config: SimConfig,
    pub clock: Arc<SimulatedClock>,
    pub state: Mutex<WorldState>,
}

impl WorldState {
    /// Restarts the fault streams and the frame numbering from a key, so that what happens from
    /// here on depends only on (fault seed, key) and not on what happened before.
    pub(crate) fn restart_streams(&mut self, fault_seed: u64, key: u64) {
        let k = key.wrapping_mul(0x9E37_79B9_7F4A_7C15);
        self.rng_turntable = ChaCha8Rng::seed_from_u64(fault_seed ^ 0x7475_726E ^ k);
        self.rng_camera = ChaCha8Rng::seed_from_u64(fault_seed ^ 0x6361_6D65 ^ k.rotate_left(17));
        self.rng_lamp = ChaCha8Rng::seed_from_u64(fault_seed ^ 0x6C61_6D70 ^ k.rotate_left(34));
        self.frame_counter = key << 24;
        self.lamp_fault_scale = 1.0;
        self.lamp_event = None;
    }
}

impl World {
    pub fn new(scene: Arc<Scene>, config: SimConfig, clock: Arc<SimulatedClock>) -> Self {
        let f = config.faults.seed;
        let stray = Arc::new(scene.stray_rate_e());
        let state = WorldState {
            angle_deg: 0.0,
            homed: false,
            speed: config.timing.turntable_speed_deg_per_s,
            lamp_on: false,
            lamp_on_since: 0.0,
            lamp_fault_scale: 1.0,
            lamp_event: None,
            exposure_s: 0.01,
            frame_counter: 0,
            camera_connected: true,
            cache_angle: None,
            cache_rate: Arc::new(Vec::new()),
            stray_rate: stray,
            rng_turntable: ChaCha8Rng::seed_from_u64(f ^ 0x7475_726E),
            rng_camera: ChaCha8Rng::seed_from_u64(f ^ 0x6361_6D65),
            rng_lamp: ChaCha8Rng::seed_from_u64(f ^ 0x6C61_6D70),
        };
        Self {
            scene,
            config,
            clock,
            state: Mutex::new(state),
        }
    }

    pub fn lock(&self) -> MutexGuard<'_, WorldState> {
        // A panic while holding the lock cannot leave the state half-updated in a way that
        // matters more than the panic itself; recover the guard.
        self.state.lock().unwrap_or_else(|p| p.into_inner())
    }

    fn now_s(&self) -> f64 {
        self.clock.seconds()
    }

    /// Lamp output relative to nominal at the current time (0 when off).
    fn lamp_output(&self, st: &WorldState) -> f64 {
        if !st.lamp_on {
            return 0.0;
        }
        let on_for = self.now_s() - st.lamp_on_since;
        let w = self.config.lamp.warm_up_s;
        let warm = if w > 0.0 && on_for < w {
            1.0 - WARM_UP_DEFICIT * (1.0 - on_for / w)
        } else {
            1.0
        };
        warm * st.lamp_fault_scale
    }
}

fn roll(rng: &mut ChaCha8Rng, p: f64) -> bool {
    p > 0.0 && rng.gen::<f64>() < p
}

/// The simulated turntable.
pub struct SimTurntable {
    pub(crate) world: Arc<World>,
}

impl Turntable for SimTurntable {
    fn home(&mut self, timeout: Duration) -> HalResult<()> {
        let w = &self.world;
        let mut st = w.lock();
        let t = st.angle_deg.abs() / st.speed + w.config.timing.homing_overhead_s;
        if t > timeout.as_secs_f64() {
            w.clock.advance(timeout);
            return Err(HalError::Timeout {
                device: DeviceKind::Turntable,
                operation: "homing".into(),
                after: timeout,
            });
        }
        w.clock.advance(Duration::from_secs_f64(t));
        st.angle_deg = 0.0;
        st.homed = true;
        Ok(())
    }

    fn move_to(&mut self, angle_deg: f64, timeout: Duration) -> HalResult<()> {
        if !(angle_deg.is_finite() && angle_deg.abs() <= 360.0) {
            return Err(HalError::InvalidArgument(format!(
                "turntable angle {angle_deg}° outside ±360°"
            )));
        }
        let w = &self.world;
        let mut st = w.lock();
        if !st.homed {
            return Err(HalError::NotHomed);
        }
        let faults = &w.config.faults;
        let travel = (angle_deg - st.angle_deg).abs();
        let t = travel / st.speed + w.config.timing.settle_s;
        let from = st.angle_deg;
        if roll(&mut st.rng_turntable, faults.turntable_timeout) || t > timeout.as_secs_f64() {
            let frac = (timeout.as_secs_f64() * st.speed / travel.max(1e-12)).min(1.0);
            let frac = frac * st.rng_turntable.gen_range(0.2..0.8);
            st.angle_deg = from + (angle_deg - from) * frac;
            // As with the GRBL driver: a move that timed out leaves the position uncertain.
            st.homed = false;
            w.clock.advance(timeout);
            tracing::debug!("sim turntable: move to {angle_deg}° timed out");
            return Err(HalError::Timeout {
                device: DeviceKind::Turntable,
                operation: format!("move to {angle_deg:.3}°"),
                after: timeout,
            });
        }
        w.clock.advance(Duration::from_secs_f64(t));
        if roll(&mut st.rng_turntable, faults.turntable_lost_steps) {
            let err = st.rng_turntable.gen_range(0.05..2.0)
                * if st.rng_turntable.gen() { 1.0 } else { -1.0 };
            st.angle_deg = angle_deg + err;
            st.homed = false;
            tracing::debug!("sim turntable: lost steps moving to {angle_deg}°");
            return Err(HalError::LostPosition {
                detail: format!("stepper lost steps moving to {angle_deg:.3}°"),
            });
        }
        st.angle_deg = angle_deg;
        Ok(())
    }

    fn angle(&mut self) -> HalResult<f64> {
        let st = self.world.lock();
        if !st.homed {
            return Err(HalError::NotHomed);
        }
        Ok(st.angle_deg)
    }

    fn speed(&self) -> f64 {
        self.world.lock().speed
    }

    fn set_speed(&mut self, deg_per_s: f64) -> HalResult<()> {
        if !(deg_per_s.is_finite() && deg_per_s > 0.0) {
            return Err(HalError::InvalidArgument(format!(
                "turntable speed {deg_per_s}"
            )));
        }
        self.world.lock().speed = deg_per_s;
        Ok(())
    }

    fn reconnect(&mut self) -> HalResult<()> {
        self.world.lock().homed = false;
        Ok(())
    }
}

/// The simulated lamp.
pub struct SimLamp {
    pub(crate) world: Arc<World>,
}

impl Lamp for SimLamp {
    fn set_on(&mut self, on: bool) -> HalResult<()> {
        let now = self.world.now_s();
        let mut st = self.world.lock();
        if on && !st.lamp_on {
            st.lamp_on_since = now;
        }
        st.lamp_on = on;
        st.lamp_fault_scale = 1.0;
        if on {
            st.lamp_event = None;
        }
        Ok(())
    }

    fn state(&mut self) -> HalResult<LampState> {
        let now = self.world.now_s();
        let mut st = self.world.lock();
        if let Some(ev) = st.lamp_event.take() {
            return Err(match ev {
                LampEvent::Dropout { at_s } => HalError::LampDropout { at_s },
                LampEvent::Flicker { change, at_s } => {
                    st.lamp_fault_scale = 1.0;
                    HalError::LampFlicker {
                        relative_change: change,
                        at_s,
                    }
                }
            });
        }
        if !st.lamp_on {
            return Ok(LampState::Off);
        }
        let remaining = self.world.config.lamp.warm_up_s - (now - st.lamp_on_since);
        Ok(if remaining > 0.0 {
            LampState::WarmingUp {
                remaining_s: remaining,
            }
        } else {
            LampState::Stable
        })
    }

    fn warm_up_s(&self) -> f64 {
        self.world.config.lamp.warm_up_s
    }

    fn wait_stable(&mut self, timeout: Duration) -> HalResult<()> {
        match self.state()? {
            LampState::Stable => Ok(()),
            LampState::Off => Err(HalError::LampNotStable {
                detail: "lamp is off".into(),
            }),
            LampState::WarmingUp { remaining_s } => {
                if remaining_s > timeout.as_secs_f64() {
                    self.world.clock.advance(timeout);
                    Err(HalError::Timeout {
                        device: DeviceKind::Lamp,
                        operation: "wait for stable output".into(),
                        after: timeout,
                    })
                } else {
                    self.world
                        .clock
                        .advance(Duration::from_secs_f64(remaining_s));
                    Ok(())
                }
            }
        }
    }
}

/// The simulated camera.
pub struct SimCamera {
    pub(crate) world: Arc<World>,
}

impl SimCamera {
    fn check_connected(st: &WorldState) -> HalResult<()> {
        if st.camera_connected {
            Ok(())
        } else {
            Err(HalError::Disconnected {
                device: DeviceKind::Camera,
                detail: "simulated camera is disconnected; reconnect".into(),
            })
        }
    }

    fn take(&mut self, exposure_s: f64, covered: bool, timeout: Duration) -> HalResult<BayerFrame> {
        let w = self.world.clone();
        let mut st = w.lock();
        Self::check_connected(&st)?;
        let faults = &w.config.faults;
        let start = w.now_s();
        let busy = exposure_s + w.config.timing.readout_s;
        if busy > timeout.as_secs_f64() {
            w.clock.advance(timeout);
            return Err(HalError::Timeout {
                device: DeviceKind::Camera,
                operation: format!("capture of {exposure_s} s"),
                after: timeout,
            });
        }
        if roll(&mut st.rng_camera, faults.camera_disconnect) {
            st.camera_connected = false;
            return Err(HalError::Disconnected {
                device: DeviceKind::Camera,
                detail: "simulated bus reset".into(),
            });
        }
        st.frame_counter += 1;
        let frame_number = st.frame_counter;
        // Lamp faults strike somewhere inside this exposure.
        if st.lamp_on && roll(&mut st.rng_lamp, faults.lamp_dropout) {
            st.lamp_on = false;
            st.lamp_event = Some(LampEvent::Dropout {
                at_s: start + exposure_s * 0.5,
            });
        }
        if st.lamp_on && roll(&mut st.rng_lamp, faults.lamp_flicker) {
            let sign = if st.rng_lamp.gen() { 1.0 } else { -1.0 };
            let change = sign * faults.lamp_flicker_magnitude.max(1e-3);
            st.lamp_fault_scale *= 1.0 + change;
            st.lamp_event = Some(LampEvent::Flicker {
                change,
                at_s: start + exposure_s * 0.5,
            });
        }
        if roll(&mut st.rng_camera, faults.camera_frame_drop) {
            w.clock.advance(Duration::from_secs_f64(busy));
            return Err(HalError::FrameDropped { frame_number });
        }
        let temp = w.config.sensor.temperature_c;
        let (lamp_scale, base) = if covered {
            (0.0, None)
        } else {
            (w.lamp_output(&st), Some(st.stray_rate.clone()))
        };
        let angle_key = st.angle_deg.to_bits();
        if lamp_scale > 0.0 && st.cache_angle != Some(angle_key) {
            st.cache_rate = Arc::new(w.scene.lamp_rate_e(st.angle_deg));
            st.cache_angle = Some(angle_key);
        }
        let npx = w.scene.width() * w.scene.height();
        let zeros;
        let lamp_rate: &[f32] = if lamp_scale > 0.0 {
            &st.cache_rate
        } else {
            zeros = vec![0f32; npx];
            &zeros
        };
        let zeros2;
        let base_rate: &[f32] = match &base {
            Some(b) => b,
            None => {
                zeros2 = vec![0f32; npx];
                &zeros2
            }
        };
        let samples = w
            .scene
            .expose(
                lamp_rate,
                lamp_scale,
                base_rate,
                exposure_s,
                temp,
                frame_number,
            )
            .map_err(|e| HalError::InvalidArgument(e.to_string()))?;
        let corrupt = roll(&mut st.rng_camera, faults.camera_corrupted_frame);
        let pick = st.rng_camera.gen::<u64>();
        drop(st);
        w.clock.advance(Duration::from_secs_f64(busy));
        let (width, height) = (w.scene.width(), w.scene.height());
        let samples = if corrupt {
            // Bit errors on the link: the frame travels through the real unpacking path, which
            // rejects it.
            let mut raw = pack_bayer10(Bayer10Format::Lsb16, &samples, width, height)
                .map_err(|e| HalError::InvalidArgument(e.to_string()))?;
            let i = (pick as usize % (width * height)) * 2 + 1;
            raw[i] |= 0x80;
            unpack_bayer10(Bayer10Format::Lsb16, &raw, width, height, None)?
        } else {
            samples
        };
        BayerFrame::new(
            width,
            height,
            w.config.sensor.bit_depth,
            w.scene.pattern(),
            samples,
            exposure_s,
            start,
            temp,
            frame_number,
        )
    }
}

impl Camera for SimCamera {
    fn info(&self) -> CameraInfo {
        let w = &self.world;
        CameraInfo {
            name: format!("simulated Retiga 1300 ({})", w.scene.truth().material),
            width: w.scene.width(),
            height: w.scene.height(),
            bit_depth: w.config.sensor.bit_depth,
            pattern: w.scene.pattern(),
            min_exposure_s: w.config.min_exposure_s,
            max_exposure_s: w.config.max_exposure_s,
        }
    }

    fn set_exposure(&mut self, seconds: f64) -> HalResult<()> {
        let (lo, hi) = (
            self.world.config.min_exposure_s,
            self.world.config.max_exposure_s,
        );
        if !(seconds.is_finite() && seconds >= lo && seconds <= hi) {
            return Err(HalError::InvalidArgument(format!(
                "exposure {seconds} s outside {lo}..{hi} s"
            )));
        }
        let mut st = self.world.lock();
        Self::check_connected(&st)?;
        st.exposure_s = seconds;
        Ok(())
    }

    fn exposure(&self) -> f64 {
        self.world.lock().exposure_s
    }

    fn capture(&mut self, timeout: Duration) -> HalResult<BayerFrame> {
        let e = self.world.lock().exposure_s;
        self.take(e, false, timeout)
    }

    fn capture_dark(&mut self, seconds: f64, timeout: Duration) -> HalResult<BayerFrame> {
        let (lo, hi) = (
            self.world.config.min_exposure_s,
            self.world.config.max_exposure_s,
        );
        if !(seconds.is_finite() && seconds >= lo && seconds <= hi) {
            return Err(HalError::InvalidArgument(format!(
                "dark exposure {seconds} s outside {lo}..{hi} s"
            )));
        }
        self.take(seconds, true, timeout)
    }

    fn sensor_temperature_c(&mut self) -> HalResult<f64> {
        let st = self.world.lock();
        Self::check_connected(&st)?;
        Ok(self.world.config.sensor.temperature_c)
    }

    fn reconnect(&mut self) -> HalResult<()> {
        self.world.lock().camera_connected = true;
        Ok(())
    }
}

/// Keeps `Clock` in scope for trait-object coercions.
pub(crate) fn as_clock(c: Arc<SimulatedClock>) -> Arc<dyn Clock> {
    c
}
