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
//! The gantry of the thesis's chapter 3: a lamp on a turntable arm orbits a spherical sample while
//! a fixed 10-bit Bayer camera photographs it. This crate defines
//!
//! * the device traits [`Turntable`], [`Lamp`], [`Camera`], [`Clock`] and the [`Rig`] bundling
//!   them (implemented for real hardware here and by the simulator in `hal-sim`);
//! * the rig's geometry ([`geometry`]): camera intrinsics and pose, lamp circle and sample
//!   sphere, shared by the simulator's ground truth and the calibration file;
//! * raw frames ([`BayerFrame`]) and unpacking of 10-bit Bayer layouts ([`unpack`]);
//! * the GRBL 1.1 protocol and, with feature `serial`, its serial driver for turntable and lamp
//!   ([`grbl`]);
//! * a V4L2 camera through `nokhwa` (feature `camera-v4l`) and USB discovery through `rusb`
//!   (feature `usb`);
//! * the TOML rig configuration ([`config`]) and [`open_real_rig`].
//!
//! Every call reports failure as a [`HalError`], whose [`HalError::kind`] ([`ErrorKind`]) is what
//! a retry policy matches on; devices that are absent fail at once with a
//! message naming them.

#![warn(missing_docs)]

pub mod clock;
pub mod config;
pub mod device;
pub mod error;
pub mod frame;
pub mod geometry;
pub mod grbl;
pub mod positions;
pub mod unpack;
#[cfg(feature = "usb")]
pub mod usb;
#[cfg(feature = "camera-v4l")]
pub mod v4l;

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
