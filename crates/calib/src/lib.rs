//! # calib — geometric calibration of the BRDF gantry (seed §3.2)
//!
//! Before a capture the rig's geometry must be known: the 3-D ray each pixel sees, the lamp
//! position at every turntable angle and the sample sphere. This crate implements the seed's
//! procedure:
//!
//! * [`corners`]: checkerboard inner corners in raw Bayer frames, with sub-pixel refinement;
//! * [`frames`]: stacking repeated exposures and flat-field correction of the target images;
//! * [`intrinsics`]: Zhang's method — homographies, closed form, Levenberg–Marquardt on
//!   fx, fy, cx, cy, k1, k2 and the board poses;
//! * [`extrinsics`]: camera pose from digitizer-tip/pixel correspondences (DLT, then LM);
//! * [`lamp`]: lamp circle from digitized lamp positions (plane, circle fit, reference angle);
//! * [`sphere`]: sphere centre from digitized surface points and the caliper diameter;
//! * [`schema`]: the versioned calibration file ([`Calibration`]) consumed by binning;
//! * [`protocol`]: the target poses to show the camera ([`plan_board_poses`]);
//! * [`pipeline`]: everything in one call ([`calibrate`]) and the output writers.

#![warn(missing_docs)]
// `!(x > 0.0)` is used on purpose: NaN must fail these checks.
#![allow(clippy::neg_cmp_op_on_partial_ord)]

pub mod corners;
pub mod error;
pub mod extrinsics;
pub mod frames;
mod geom;
pub mod intrinsics;
pub mod io;
pub mod lamp;
mod lattice;
mod lm;
pub mod pipeline;
pub mod protocol;
pub mod schema;
#[cfg(feature = "sim")]
pub mod sim;
pub mod sphere;

pub use corners::{detect_board, detect_board_flat, detect_board_gray, CornerImage, CornerOptions, GrayImage};
pub use error::{CalibError, CalibResult};
pub use extrinsics::{fit_extrinsics, ExtrinsicFit, TipCorrespondence};
pub use frames::{stack_frames, FlatField};
pub use geom::rotation_angle_between;
pub use intrinsics::{fit_intrinsics, BoardGeometry, BoardPose, IntrinsicFit, IntrinsicOptions};
pub use lamp::{fit_lamp_circle, LampFit, LampReading};
pub use pipeline::{calibrate, CalibrationInputs, CalibrationOptions, CalibrationRun};
pub use protocol::{plan_board_poses, DigitizerProtocol, TargetProtocol};
pub use schema::{
    Calibration, CameraIntrinsics, CameraPose, FitQuality, LampCircle, SphereGeometry,
    CALIBRATION_VERSION,
};
pub use sphere::{fit_sphere, SphereFit};
