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
//! The calibration runs in this order:
//!
//! 1. **Targets.** [`TargetProtocol`] says which board ([`BoardGeometry`]) to show the camera
//!    and in which poses ([`plan_board_poses`]); repeated exposures of a pose are summed by
//!    [`stack_frames`] and flat-fielded with a [`FlatField`].
//! 2. **Corners.** [`detect_board`] finds the inner corners in raw Bayer frames
//!    ([`detect_board_gray`] in grey images, such as photographs), refined to sub-pixel
//!    accuracy ([`CornerOptions`]).
//! 3. **Camera.** [`fit_intrinsics`] is Zhang's method: homographies, closed form,
//!    Levenberg–Marquardt on fx, fy, cx, cy, the Brown–Conrady terms of a [`DistortionModel`] and
//!    the [`BoardPose`]s. [`fit_extrinsics`] gives the camera pose from digitizer-tip/pixel
//!    correspondences ([`TipCorrespondence`]; DLT, then Levenberg–Marquardt).
//! 4. **Lamp and sphere.** [`fit_lamp_circle`] fits the lamp circle to digitized lamp positions
//!    (plane, circle, reference angle), [`fit_sphere`] the sphere centre to digitized surface
//!    points and the caliper diameter.
//! 5. **Everything at once.** [`calibrate`] runs steps 2–4 on [`CalibrationInputs`] (read from
//!    an operator's files by [`read_session`]) and returns a [`CalibrationRun`]; [`write_run`]
//!    stores it. The result is a [`Calibration`], the versioned `calibration.json` that binning
//!    consumes.
//!
//! Besides the rig's procedure: [`calibrate_photos`] calibrates a camera from a folder of
//! photographs alone, with per-view reports ([`PhotoCalibration`]), behind
//! `gantry calibrate intrinsics` ([`IntrinsicsJob`]); [`OpenCvCamera`] reads and writes
//! OpenCV's camera file layout. With feature `sim`, `simulate_session` and
//! `calibrate_rig_session` run the whole procedure on the simulated rig.

#![warn(missing_docs)]
// `!(x > 0.0)` is used on purpose: NaN must fail these checks.
#![allow(clippy::neg_cmp_op_on_partial_ord)]

mod board;
mod corners;
mod error;
mod extrinsics;
mod frames;
mod geom;
mod intrinsics;
mod io;
mod job;
mod lamp;
mod lattice;
mod lm;
mod opencv;
mod photos;
mod pipeline;
mod protocol;
mod schema;
mod session;
#[cfg(feature = "sim")]
mod sim;
mod sphere;

pub use corners::SubpixelMethod;
pub use io::{
    digitizer_csv, frame_png16, parse_digitizer_csv, read_digitizer_csv, read_frame_png16,
    write_atomic, DigitizerLog,
};
pub use opencv::OpenCvCamera;
pub use pipeline::digitizer_log;
pub use schema::Point3;
pub use session::{
    glob_files, inputs_from, parse_grid, read_frames_dir, read_session, TruthComparison,
};
#[cfg(feature = "sim")]
pub use sim::{
    calibrate_rig_session, calibration_from_truth, simulate_rig_session, simulate_session,
    SessionNoise, SimulatedSession,
};

pub use board::BoardGeometry;
pub use corners::{
    balanced_image, detect_board, detect_board_flat, detect_board_gray, green_image, CornerImage,
    CornerOptions, GrayImage,
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
    CALIBRATION_VERSION, OLDEST_CALIBRATION_VERSION,
};
pub use sphere::{fit_sphere, SphereFit};
