//! # gantry-hal — devices of the BRDF measurement gantry
//!
//! ```
//! use gantry_hal::{pack_bayer10, unpack_bayer10, Bayer10Format, BayerFrame, BayerPattern};
//!
//! // a raw 10-bit frame, packed as the camera delivers it and unpacked again
//! let data: Vec<u16> = (0..16).map(|i| (i * 60) as u16).collect();
//! let frame = BayerFrame::new(4, 4, 10, BayerPattern::Rggb, data.clone(), 0.01, 0.0, 25.0, 0)
//!     .unwrap();
//! let packed = pack_bayer10(Bayer10Format::MipiPacked, &frame.data, 4, 4).unwrap();
//! assert_eq!(packed.len(), 16 * 5 / 4); // four pixels in five bytes
//! assert_eq!(unpack_bayer10(Bayer10Format::MipiPacked, &packed, 4, 4, None).unwrap(), data);
//! // a sample above 10 bits is a corrupted frame, not a panic
//! assert!(BayerFrame::new(1, 1, 10, BayerPattern::Rggb, vec![1024], 0.01, 0.0, 25.0, 0).is_err());
//! ```
//!
//! The gantry of thesis §3.1: a lamp on a turntable arm orbits a spherical sample while a fixed
//! 10-bit Bayer camera photographs it. This crate is the hardware abstraction layer that every
//! capture crate talks to, shaped after `embedded-hal`: small device traits, one error type per
//! device call with a [`HalError::kind`] into a non-exhaustive [`ErrorKind`], and the drivers
//! for real hardware in their own public modules.
//!
//! A newcomer meets the crate in the order a capture uses it:
//!
//! 1. **Configuration.** [`RigConfig`] is the TOML rig file (`docs/rig.example.toml`): which
//!    [`Backend`] (`sim` or `real`), the GRBL controller, the camera, the USB devices that must
//!    be present. [`open_real_rig`] turns a `real` configuration into devices; the simulator
//!    (`hal-sim`) reads the `[sim]` table itself.
//! 2. **Devices.** The traits [`Turntable`], [`Lamp`] and [`Camera`], and the [`Clock`] they
//!    run on ([`SystemClock`] for hardware, [`SimulatedClock`] for the simulator), bundled in a
//!    [`Rig`]. They are implemented here for real hardware and by `hal_sim::SimRig`.
//! 3. **Frames.** A [`Camera`] delivers raw [`BayerFrame`]s; [`unpack_bayer10`] reads the 10-bit
//!    layouts V4L2 cameras send ([`Bayer10Format`]), and [`encode_frames`]/[`decode_frames`] are
//!    the frame-file codec a capture keeps raw frames in.
//! 4. **Geometry.** [`RigGeometry`] (camera intrinsics and pose, lamp circle, sample sphere) turns
//!    pixels into world rays and turntable angles into lamp positions; it is the one definition
//!    shared by the simulator's ground truth and the calibration file of `calib` (thesis §3.2).
//!    [`position_angles`] spaces the lamp positions of a capture (thesis §3.4).
//! 5. **Errors.** Every device call returns [`HalResult`]. A retry policy matches on
//!    [`HalError::kind`], never on the driver's message; devices that are absent fail at once
//!    with [`HalError::DeviceAbsent`] naming them.
//!
//! The drivers live in public modules: [`grbl`] (the GRBL 1.1 protocol, always available, and
//! with feature `serial` the serial driver for turntable and lamp), `v4l` (a V4L2 camera through
//! `nokhwa`, feature `camera-v4l`) and `usb` (USB discovery through `rusb`, feature `usb`).

#![warn(missing_docs)]

mod clock;
mod config;
mod device;
mod error;
mod frame;
mod geometry;
pub mod grbl;
mod positions;
mod unpack;
#[cfg(feature = "usb")]
pub mod usb;
#[cfg(feature = "camera-v4l")]
pub mod v4l;

pub use config::{UsbDeviceSpec, V4lCameraConfig};

pub use clock::{Clock, SimulatedClock, SystemClock};
pub use config::{Backend, RigConfig};
pub use device::{Camera, CameraInfo, Lamp, LampState, Rig, Turntable};
pub use error::{DeviceKind, ErrorKind, HalError, HalResult};
pub use frame::{decode_frames, encode_frames, BayerFrame, BayerPattern, FrameFileError};
pub use geometry::{
    CameraIntrinsics, CameraPose, GeometryError, GeometryResult, LampCircle, Point3, RigGeometry,
    SphereGeometry,
};
pub use positions::{position_angles, LAST_POSITION_DEG, THESIS_POSITIONS};
pub use unpack::{pack_bayer10, unpack_bayer10, Bayer10Format};

use std::sync::Arc;

/// Opens the real devices a configuration names: checks the required USB devices (feature
/// `usb`), opens the GRBL controller (feature `serial`) and the camera (feature `camera-v4l`). The first device
/// that is missing stops the opening with [`HalError::DeviceAbsent`] naming it.
///
/// # Examples
///
/// On a machine without the gantry the first device fails at once, with an error that names
/// it (or, in a build without the `serial` feature, the feature that would drive it):
///
/// ```
/// use gantry_hal::{open_real_rig, ErrorKind, RigConfig};
///
/// let cfg = RigConfig::from_toml_str(r#"
///     backend = "real"
///     [motion]
///     port = "/dev/no-such-grbl-port"
///     [camera]
///     index = 99
///     width = 1300
///     height = 1030
///     pixel_format = "mipi_packed"
/// "#).unwrap();
/// let err = open_real_rig(&cfg).unwrap_err();
/// assert!(matches!(err.kind(), ErrorKind::Absent | ErrorKind::Config), "{err}");
/// ```
pub fn open_real_rig(cfg: &RigConfig) -> HalResult<Rig> {
    cfg.validate()?;
    if !cfg.usb.is_empty() {
        #[cfg(feature = "usb")]
        usb::require_all(&cfg.usb)?;
        #[cfg(not(feature = "usb"))]
        tracing::warn!("USB presence checks skipped: built without feature 'usb'");
    }
    let motion = cfg
        .motion
        .clone()
        .ok_or_else(|| HalError::Config("missing [motion] section".into()))?;
    let camera_cfg = cfg
        .camera
        .clone()
        .ok_or_else(|| HalError::Config("missing [camera] section".into()))?;
    let (turntable, lamp) = open_motion(motion)?;
    let camera = open_camera(camera_cfg)?;
    Ok(Rig {
        turntable,
        lamp,
        camera,
        clock: Arc::new(SystemClock::new()),
    })
}

type MotionDevices = (Box<dyn Turntable>, Box<dyn Lamp>);

#[cfg(feature = "serial")]
fn open_motion(motion: grbl::GrblConfig) -> HalResult<MotionDevices> {
    use std::sync::Mutex;
    let ctl = Arc::new(Mutex::new(grbl::GrblController::open(motion)?));
    let turntable = Box::new(grbl::GrblTurntable::new(ctl.clone())?);
    let lamp = Box::new(grbl::GrblLamp::new(ctl)?);
    Ok((turntable, lamp))
}

#[cfg(not(feature = "serial"))]
fn open_motion(motion: grbl::GrblConfig) -> HalResult<MotionDevices> {
    Err(HalError::FeatureMissing {
        feature: "serial",
        what: format!("GRBL controller on {}", motion.port),
    })
}

#[cfg(feature = "camera-v4l")]
fn open_camera(c: config::V4lCameraConfig) -> HalResult<Box<dyn Camera>> {
    Ok(Box::new(v4l::V4lCamera::open(c)?))
}

#[cfg(not(feature = "camera-v4l"))]
fn open_camera(c: config::V4lCameraConfig) -> HalResult<Box<dyn Camera>> {
    Err(HalError::FeatureMissing {
        feature: "camera-v4l",
        what: format!("V4L2 camera /dev/video{}", c.index),
    })
}
