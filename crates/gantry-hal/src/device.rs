//! The device traits of the gantry and the [`Rig`] that bundles them.

use crate::clock::Clock;
use crate::error::HalResult;
use crate::frame::{BayerFrame, BayerPattern};
use serde::{Deserialize, Serialize};
use std::sync::Arc;
use std::time::Duration;

/// The turntable that carries the lamp arm around the sample.
///
/// Like every device trait of the crate, its calls block until done or until their timeout,
/// measured on the rig's [`Clock`].
///
/// # Examples
///
/// A driver implements the trait and reports its faults as [`HalError`](crate::HalError)s; a
/// caller decides what to do from the error's [`kind`](crate::HalError::kind), whatever the
/// driver:
///
/// ```
/// use gantry_hal::{ErrorKind, HalError, HalResult, Turntable};
/// use std::time::Duration;
///
/// /// A turntable that moves instantly and must be homed first, as a GRBL controller must.
/// struct Instant { angle: Option<f64>, speed: f64 }
///
/// impl Turntable for Instant {
///     fn home(&mut self, _timeout: Duration) -> HalResult<()> {
///         self.angle = Some(0.0);
///         Ok(())
///     }
///     fn move_to(&mut self, angle_deg: f64, _timeout: Duration) -> HalResult<()> {
///         let angle = self.angle.as_mut().ok_or(HalError::NotHomed)?;
///         *angle = angle_deg;
///         Ok(())
///     }
///     fn angle(&mut self) -> HalResult<f64> {
///         self.angle.ok_or(HalError::NotHomed)
///     }
///     fn speed(&self) -> f64 {
///         self.speed
///     }
///     fn set_speed(&mut self, deg_per_s: f64) -> HalResult<()> {
///         self.speed = deg_per_s;
///         Ok(())
///     }
///     fn reconnect(&mut self) -> HalResult<()> {
///         self.angle = None; // position unknown until homed again
///         Ok(())
///     }
/// }
///
/// let mut table = Instant { angle: None, speed: 2.0 };
/// let wait = Duration::from_secs(10);
/// let err = table.move_to(45.0, wait).unwrap_err();
/// assert_eq!(err.kind(), ErrorKind::NeedsHoming); // the retry policy homes, then retries
/// table.home(wait).unwrap();
/// table.move_to(45.0, wait).unwrap();
/// assert_eq!(table.angle().unwrap(), 45.0);
/// ```
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
///
/// A capture job owns one `Rig`: [`crate::open_real_rig`] builds it from a [`crate::RigConfig`]
/// for hardware, `hal_sim::SimRig::rig` for the simulator. All device calls block until done or
/// until their timeout; none of them sleeps on the wall clock when the rig runs on a simulated
/// [`Clock`] (a [`crate::SimulatedClock`] only advances), so a simulated capture of hours runs
/// in seconds.
///
/// # Examples
///
/// A rig assembled from stand-in devices (hidden below: they accept every call) on a simulated
/// clock, driven through the traits only, as a capture job drives it:
///
/// ```
/// use gantry_hal::{Clock, Rig, SimulatedClock};
/// use std::sync::Arc;
/// use std::time::Duration;
/// # use gantry_hal::{BayerFrame, BayerPattern, Camera, CameraInfo, HalResult, Lamp, LampState, Turntable};
/// # struct Table(f64);
/// # impl Turntable for Table {
/// #     fn home(&mut self, _: Duration) -> HalResult<()> { self.0 = 0.0; Ok(()) }
/// #     fn move_to(&mut self, a: f64, _: Duration) -> HalResult<()> { self.0 = a; Ok(()) }
/// #     fn angle(&mut self) -> HalResult<f64> { Ok(self.0) }
/// #     fn speed(&self) -> f64 { 1.0 }
/// #     fn set_speed(&mut self, _: f64) -> HalResult<()> { Ok(()) }
/// #     fn reconnect(&mut self) -> HalResult<()> { Ok(()) }
/// # }
/// # struct Bulb(bool);
/// # impl Lamp for Bulb {
/// #     fn set_on(&mut self, on: bool) -> HalResult<()> { self.0 = on; Ok(()) }
/// #     fn state(&mut self) -> HalResult<LampState> {
/// #         Ok(if self.0 { LampState::Stable } else { LampState::Off })
/// #     }
/// #     fn warm_up_s(&self) -> f64 { 0.0 }
/// #     fn wait_stable(&mut self, _: Duration) -> HalResult<()> { Ok(()) }
/// # }
/// # struct Cam(f64, Arc<SimulatedClock>);
/// # impl Camera for Cam {
/// #     fn info(&self) -> CameraInfo {
/// #         CameraInfo { name: "stand-in".into(), width: 2, height: 2, bit_depth: 10,
/// #             pattern: BayerPattern::Rggb, min_exposure_s: 1e-4, max_exposure_s: 60.0 }
/// #     }
/// #     fn set_exposure(&mut self, s: f64) -> HalResult<()> { self.0 = s; Ok(()) }
/// #     fn exposure(&self) -> f64 { self.0 }
/// #     fn capture(&mut self, _: Duration) -> HalResult<BayerFrame> {
/// #         self.1.advance(Duration::from_secs_f64(self.0));
/// #         BayerFrame::new(2, 2, 10, BayerPattern::Rggb, vec![64; 4], self.0, self.1.seconds(), 25.0, 0)
/// #     }
/// #     fn capture_dark(&mut self, s: f64, t: Duration) -> HalResult<BayerFrame> {
/// #         self.set_exposure(s)?; self.capture(t)
/// #     }
/// #     fn sensor_temperature_c(&mut self) -> HalResult<f64> { Ok(25.0) }
/// #     fn reconnect(&mut self) -> HalResult<()> { Ok(()) }
/// # }
///
/// let clock = Arc::new(SimulatedClock::new());
/// let mut rig = Rig {
///     turntable: Box::new(Table(0.0)),
///     lamp: Box::new(Bulb(false)),
///     camera: Box::new(Cam(0.01, clock.clone())),
///     clock: clock.clone(),
/// };
/// let wait = Duration::from_secs(60);
/// rig.turntable.home(wait)?;
/// rig.turntable.move_to(30.0, wait)?;
/// rig.lamp.set_on(true)?;
/// rig.lamp.wait_stable(wait)?;
/// rig.camera.set_exposure(20.0)?;
/// let frame = rig.camera.capture(wait)?;
/// assert_eq!((frame.width, frame.height), (2, 2));
/// // twenty simulated seconds passed, no wall-clock time
/// assert!(rig.clock.is_simulated());
/// assert_eq!(rig.clock.now(), Duration::from_secs(20));
/// # Ok::<(), gantry_hal::HalError>(())
/// ```
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
