//! The whole calibration in one call: corners in every target image, intrinsics, extrinsics,
//! lamp circle, sphere; and the writer of a whole run.

use crate::board::BoardGeometry;
use crate::corners::{detect_board_flat, CornerOptions};
use crate::error::{CalibError, CalibResult};
use crate::extrinsics::{fit_extrinsics, ExtrinsicFit, TipCorrespondence};
use crate::frames::FlatField;
use crate::intrinsics::{fit_intrinsics, IntrinsicFit, IntrinsicOptions};
use crate::io::DigitizerLog;
use crate::lamp::{fit_lamp_circle, LampFit, LampReading};
use crate::schema::{Calibration, FitQuality, Point3};
use crate::sphere::{fit_sphere, SphereFit};
use gantry_hal::BayerFrame;
use serde::{Deserialize, Serialize};
use std::path::{Path, PathBuf};

/// Everything measured for a calibration.
#[derive(Debug, Clone, PartialEq)]
pub struct CalibrationInputs {
    /// The checkerboard target.
    pub board: BoardGeometry,
    /// Raw frames of the target in varied poses (≥ `min_views`), one per pose: a single
    /// exposure or several summed by [`crate::stack_frames`].
    pub target_frames: Vec<BayerFrame>,
    /// Flat frames: exposures of a uniformly lit diffuser ([`crate::FlatField`]). When there
    /// are any, every target frame is flat-fielded before its corners are found.
    pub flat_frames: Vec<BayerFrame>,
    /// Digitizer-tip positions and their pixels (about 30).
    pub tips: Vec<TipCorrespondence>,
    /// Digitized lamp positions at known turntable angles (about 30).
    pub lamp: Vec<LampReading>,
    /// Digitized points on the sphere surface (about 30).
    pub sphere_points: Vec<Point3>,
    /// Caliper diameter of the sphere, metres.
    pub sphere_diameter_m: f64,
}

/// Settings of [`calibrate`].
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct CalibrationOptions {
    /// Corner detector settings.
    pub corners: CornerOptions,
    /// Intrinsic fit settings.
    pub intrinsics: IntrinsicOptions,
    /// Fewest target images in which the board must be found.
    pub min_views: usize,
}

impl Default for CalibrationOptions {
    fn default() -> Self {
        Self {
            corners: CornerOptions::default(),
            intrinsics: IntrinsicOptions::default(),
            min_views: 10,
        }
    }
}

/// Result of [`calibrate`]: the calibration and every intermediate fit.
#[derive(Debug, Clone, PartialEq)]
pub struct CalibrationRun {
    /// The calibration (with [`FitQuality`]).
    pub calibration: Calibration,
    /// Detected corners per target image (`None` where the board was not found whole).
    pub corners: Vec<Option<Vec<[f64; 2]>>>,
    /// Intrinsic fit (board poses in the order of the images with corners).
    pub intrinsics: IntrinsicFit,
    /// Extrinsic fit.
    pub extrinsics: ExtrinsicFit,
    /// Lamp-circle fit.
    pub lamp: LampFit,
    /// Sphere fit.
    pub sphere: SphereFit,
}

impl CalibrationRun {
    /// RMS reprojection error of the checkerboard corners, pixels.
    pub fn reprojection_rms(&self) -> f64 {
        self.intrinsics.rms_px
    }

    /// Indices of the target images that were dropped (board not found whole).
    pub fn dropped_views(&self) -> Vec<usize> {
        self.corners
            .iter()
            .enumerate()
            .filter_map(|(i, c)| c.is_none().then_some(i))
            .collect()
    }
}

/// Runs the thesis's §3.2 procedure on `inputs`. Images in which the board is not found whole
/// (not found, or some inner corners missing) are dropped, logged and listed in
/// [`CalibrationRun::dropped_views`], as calibration tools do; fewer than `options.min_views`
/// (at least 3) remaining images is [`CalibError::TooFewViews`], which names each dropped
/// image.
pub fn calibrate(
    inputs: &CalibrationInputs,
    options: &CalibrationOptions,
) -> CalibResult<CalibrationRun> {
    inputs.board.validate()?;
    let first = inputs
        .target_frames
        .first()
        .ok_or(CalibError::TooFewPoints {
            what: "target images",
            got: 0,
            need: options.min_views.max(3),
        })?;
    let (width, height) = (first.width, first.height);
    let flat = if inputs.flat_frames.is_empty() {
        None
    } else {
        Some(FlatField::estimate(&inputs.flat_frames)?)
    };
    let mut corners = Vec::with_capacity(inputs.target_frames.len());
    let mut views = Vec::new();
    let mut dropped = Vec::new();
    for (i, frame) in inputs.target_frames.iter().enumerate() {
        if frame.width != width || frame.height != height {
            return Err(CalibError::Invalid(format!(
                "target image {i} is {}x{}, the first is {width}x{height}",
                frame.width, frame.height
            )));
        }
        match detect_board_flat(frame, flat.as_ref(), &inputs.board, &options.corners, i) {
            Ok(c) => {
                views.push(c.clone());
                corners.push(Some(c));
            }
            Err(e @ (CalibError::BoardNotFound { .. } | CalibError::TooFewCorners { .. })) => {
                tracing::warn!(image = i, error = %e, "target image dropped");
                corners.push(None);
                dropped.push(e.to_string());
            }
            Err(e) => return Err(e),
        }
    }
    let need = options.min_views.max(3);
    if views.len() < need {
        return Err(CalibError::TooFewViews {
            usable: views.len(),
            total: inputs.target_frames.len(),
            need,
            dropped: dropped.join("; "),
        });
    }
    if !dropped.is_empty() {
        tracing::info!(
            dropped = dropped.len(),
            used = views.len(),
            "calibration continues without the dropped target images"
        );
    }
    let intrinsics = fit_intrinsics(&inputs.board, &views, width, height, &options.intrinsics)?;
    tracing::info!(
        rms_px = intrinsics.rms_px,
        views = views.len(),
        "intrinsics"
    );
    let extrinsics = fit_extrinsics(&intrinsics.camera, &inputs.tips)?;
    let lamp = fit_lamp_circle(&inputs.lamp)?;
    let sphere = fit_sphere(&inputs.sphere_points, inputs.sphere_diameter_m)?;
    let mut calibration = Calibration::new(
        intrinsics.camera,
        extrinsics.pose,
        lamp.circle,
        sphere.geometry,
    );
    calibration.fit = Some(FitQuality {
        reprojection_rms_px: intrinsics.rms_px,
        target_images: views.len(),
        dropped_target_images: dropped.len(),
        distortion_model: Some(options.intrinsics.model),
        extrinsic_rms_px: extrinsics.rms_px,
        lamp_rms_m: lamp.rms_m,
        sphere_rms_m: sphere.rms_m,
    });
    calibration.validate()?;
    Ok(CalibrationRun {
        calibration,
        corners,
        intrinsics,
        extrinsics,
        lamp,
        sphere,
    })
}

/// The digitizer part of calibration inputs.
pub fn digitizer_log(inputs: &CalibrationInputs) -> DigitizerLog {
    DigitizerLog {
        tips: inputs.tips.clone(),
        lamp: inputs.lamp.clone(),
        sphere_points: inputs.sphere_points.clone(),
        sphere_diameter_m: inputs.sphere_diameter_m,
    }
}

/// Writes a run into `dir`: `calibration.json`, `truth.json` (when `truth` is given),
/// `targets/target_NN.png`, `flats/flat_NN.png` (when there are flat frames) and
/// `digitizer.csv`. Returns the paths written.
pub fn write_run(
    dir: &Path,
    inputs: &CalibrationInputs,
    run: &CalibrationRun,
    truth: Option<&Calibration>,
) -> CalibResult<Vec<PathBuf>> {
    let targets = dir.join("targets");
    std::fs::create_dir_all(&targets).map_err(crate::io::io_err(&targets))?;
    let mut written = Vec::new();
    let p = dir.join("calibration.json");
    run.calibration.write(&p)?;
    written.push(p);
    if let Some(t) = truth {
        let p = dir.join("truth.json");
        t.write(&p)?;
        written.push(p);
    }
    for (i, f) in inputs.target_frames.iter().enumerate() {
        let p = targets.join(format!("target_{i:02}.png"));
        crate::io::write_atomic(&p, &crate::io::frame_png16(f)?)?;
        written.push(p);
    }
    if !inputs.flat_frames.is_empty() {
        let flats = dir.join("flats");
        std::fs::create_dir_all(&flats).map_err(crate::io::io_err(&flats))?;
        for (i, f) in inputs.flat_frames.iter().enumerate() {
            let p = flats.join(format!("flat_{i:02}.png"));
            crate::io::write_atomic(&p, &crate::io::frame_png16(f)?)?;
            written.push(p);
        }
    }
    let p = dir.join("digitizer.csv");
    crate::io::write_atomic(
        &p,
        crate::io::digitizer_csv(&digitizer_log(inputs)).as_bytes(),
    )?;
    written.push(p);
    Ok(written)
}
