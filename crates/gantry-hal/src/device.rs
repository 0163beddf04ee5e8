//! The device traits of the gantry and the [`Rig`] that bundles them.
//!
//! All calls block until done or until their timeout; none of them sleeps on the wall clock when
//! the rig runs on a simulated [`Clock`].

use crate::clock::Clock;
use crate::error::HalResult;
use crate::frame::{BayerFrame, BayerPattern};
use serde::{Deserialize, Serialize};
use std::sync::Arc;
use std::time::Duration;

/// The turntable that carries the lamp arm around the sample.
pub trait Turntable: Send {
    /// Drives to the home switch and sets the angle to zero.
    fn home(&mut self, timeout: Duration) -> HalResult<()>;
    /// Rotates to `angle_deg` (absolute, degrees) and waits until the motion has finished.
    fn move_to(&mut self, angle_deg: f64, timeout: Duration) -> HalResult<()>;
    /// The current angle in degrees, as the controller reports it.
    fn angle(&mut self) -> HalResult<f64>;
    /// Rotation speed used for moves, degrees per second.
    fn speed(&self) -> f64;
    /// Sets the rotation speed, degrees per second.
    fn set_speed(&mut self, deg_per_s: f64) -> HalResult<()>;
    /// Re-establishes the connection after [`crate::HalError::Disconnected`]. The turntable must
    /// be homed again afterwards.
    fn reconnect(&mut self) -> HalResult<()>;
}

/// State of the light source.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case", tag = "state")]
pub enum LampState {
    /// Switched off.
    Off,
    /// On, output still drifting; stable after `remaining_s` more seconds.
    WarmingUp {
        /// Seconds until the output is stable.
        remaining_s: f64,
    },
    /// On and stable.
    Stable,
}

/// The light source.
pub trait Lamp: Send {
    /// Switches the lamp on or off.
    fn set_on(&mut self, on: bool) -> HalResult<()>;
    /// The current state. Reports, as errors, a dropout or flicker that happened since the last
    /// call ([`crate::HalError::LampDropout`], [`crate::HalError::LampFlicker`]), so a capture
    /// job calls it after each series of exposures and repeats the series on error.
    fn state(&mut self) -> HalResult<LampState>;
    /// Warm-up time after switching on, seconds.
    fn warm_up_s(&self) -> f64;
    /// Blocks until the lamp is stable or `timeout` elapses on the rig clock.
    fn wait_stable(&mut self, timeout: Duration) -> HalResult<()>;
}

/// Fixed properties of a camera.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct CameraInfo {
    /// Device name.
    pub name: String,
    /// Sensor columns.
    pub width: usize,
    /// Sensor rows.
    pub height: usize,
    /// Bits per sample.
    pub bit_depth: u8,
    /// Colour filter arrangement.
    pub pattern: BayerPattern,
    /// Shortest exposure, seconds.
    pub min_exposure_s: f64,
    /// Longest exposure, seconds.
    pub max_exposure_s: f64,
}

/// The camera.
pub trait Camera: Send {
    /// Sensor size, bit depth, pattern and exposure range.
    fn info(&self) -> CameraInfo;
    /// Sets the exposure time (seconds, within the range of [`Camera::info`]).
    fn set_exposure(&mut self, seconds: f64) -> HalResult<()>;
    /// The exposure time that will be used, seconds.
    fn exposure(&self) -> f64;
    /// Takes one frame at the current exposure.
    fn capture(&mut self, timeout: Duration) -> HalResult<BayerFrame>;
    /// Takes one frame of `seconds` with the lens covered (shutter closed / cap on).
    fn capture_dark(&mut self, seconds: f64, timeout: Duration) -> HalResult<BayerFrame>;
    /// Current sensor temperature, °C.
    fn sensor_temperature_c(&mut self) -> HalResult<f64>;
    /// Re-establishes the connection after [`crate::HalError::Disconnected`].
    fn reconnect(&mut self) -> HalResult<()>;
}

/// The devices of one gantry and the clock they run on.
pub struct Rig {
    /// The turntable carrying the lamp.
    pub turntable: Box<dyn Turntable>,
    /// The light source.
    pub lamp: Box<dyn Lamp>,
    /// The camera.
    pub camera: Box<dyn Camera>,
    /// Rig time.
    pub clock: Arc<dyn Clock>,
}

impl std::fmt::Debug for Rig {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Rig")
            .field("camera", &self.camera.info())
            .field("simulated_clock", &self.clock.is_simulated())
            .finish_non_exhaustive()
    }
}
