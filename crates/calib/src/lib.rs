//! # calib — geometric calibration of the BRDF gantry (thesis §3.2)
//!
//! Before a capture the rig's geometry must be known: the 3-D ray each pixel sees, the lamp
//! position at every turntable angle and the sample sphere. This crate implements the
//! thesis's procedure, and calibrates a camera from ordinary photographs of a checkerboard:
//!
//! ```
//! use calib::{detect_board_gray, BoardGeometry, CornerOptions, GrayImage};
//! // A 6 × 5-square board (5 × 4 inner corners) of 12-pixel squares, drawn straight on.
//! let board = BoardGeometry { squares_x: 6, squares_y: 5, square_m: 0.01 };
//! let (w, h, s, x0, y0) = (120, 100, 12.0, 24.0, 20.0);
//! let data = (0..w * h)
//!     .map(|k| {
//!         let (x, y) = ((k % w) as f64 + 0.5 - x0, (k / w) as f64 + 0.5 - y0);
//!         let (i, j) = ((x / s).floor(), (y / s).floor());
//!         let inside = i >= 0.0 && j >= 0.0 && i < 6.0 && j < 5.0;
//!         if inside && (i + j) as i64 % 2 == 0 { 0.1 } else { 0.9 }
//!     })
//!     .collect();
//! let img = GrayImage { width: w, height: h, data };
//! let corners = detect_board_gray(&img, &board, &CornerOptions::default(), 0).unwrap();
//! assert_eq!(corners.len(), 20);
//! // The first inner corner, (1, 1) squares from the board's origin, at pixel (35.5, 31.5).
//! assert!((corners[0][0] - 35.5).abs() < 0.05 && (corners[0][1] - 31.5).abs() < 0.05);
//! ```
//!
//! * [`corners`]: checkerboard inner corners in raw Bayer frames and photographs, with
//!   sub-pixel refinement;
//! * [`frames`]: stacking repeated exposures and flat-field correction of the target images;
//! * [`intrinsics`]: Zhang's method — homographies, closed form, Levenberg–Marquardt on
//!   fx, fy, cx, cy, the Brown–Conrady terms of a [`DistortionModel`] and the board poses;
//! * [`extrinsics`]: camera pose from digitizer-tip/pixel correspondences (DLT, then LM);
//! * [`lamp`]: lamp circle from digitized lamp positions (plane, circle fit, reference angle);
//! * [`sphere`]: sphere centre from digitized surface points and the caliper diameter;
//! * [`schema`]: the versioned calibration file ([`Calibration`]) consumed by binning;
//! * [`opencv`]: OpenCV's calibration file layout (`cv::FileStorage` YAML), read and written;
//! * [`photos`]: a camera calibrated from a folder of photographs, with per-view reports;
//! * [`protocol`]: the target poses to show the camera ([`plan_board_poses`]);
//! * [`pipeline`]: everything in one call ([`calibrate`]) and the writer of a whole run;
//! * [`session`]: the inputs of a calibration read from an operator's files.

#![warn(missing_docs)]
// `!(x > 0.0)` is used on purpose: NaN must fail these checks.
#![allow(clippy::neg_cmp_op_on_partial_ord)]

pub mod board;
pub mod corners;
pub mod error;
pub mod extrinsics;
pub mod frames;
mod geom;
pub mod intrinsics;
pub mod io;
mod job;
pub mod lamp;
mod lattice;
mod lm;
pub mod opencv;
pub mod photos;
pub mod pipeline;
pub mod protocol;
pub mod schema;
pub mod session;
#[cfg(feature = "sim")]
pub mod sim;
pub mod sphere;

pub use board::BoardGeometry;
pub use corners::{
    detect_board, detect_board_flat, detect_board_gray, CornerImage, CornerOptions, GrayImage,
};
pub use error::{CalibError, CalibResult};
pub use extrinsics::{fit_extrinsics, ExtrinsicFit, TipCorrespondence};
pub use frames::{stack_frames, FlatField};
pub use geom::rotation_angle_between;
pub use intrinsics::{fit_intrinsics, BoardPose, DistortionModel, IntrinsicFit, IntrinsicOptions};
pub use job::{IntrinsicsJob, IntrinsicsReport};
pub use lamp::{fit_lamp_circle, LampFit, LampReading};
pub use photos::{calibrate_photos, PhotoCalibration, PhotoOptions, ViewReport, ViewStatus};
pub use pipeline::{calibrate, write_run, CalibrationInputs, CalibrationOptions, CalibrationRun};
pub use protocol::{plan_board_poses, DigitizerProtocol, TargetProtocol};
pub use schema::{
    Calibration, CameraIntrinsics, CameraPose, FitQuality, LampCircle, RigGeometry, SphereGeometry,
    CALIBRATION_VERSION,
};
pub use sphere::{fit_sphere, SphereFit};
