//! The job behind `gantry calibrate intrinsics`: a camera from checkerboard photographs. With
//! the `cli` feature the options are also the command's arguments.

use std::fmt;
use std::path::{Path, PathBuf};

use serde::Serialize;

use crate::error::{CalibError, CalibResult};
use crate::intrinsics::DistortionModel;
use crate::photos::{calibrate_photos, write_corner_drawings, PhotoCalibration, PhotoOptions};
use crate::{BoardGeometry, ViewStatus};

/// Calibrate a camera from checkerboard photographs (PNG, JPEG, TIFF) alone, without the
/// digitizer or the rig.
#[derive(Debug, Clone)]
#[cfg_attr(feature = "cli", derive(clap::Args))]
pub struct IntrinsicsJob {
    /// The photographs: a file pattern with one `*` in the name, e.g. 'DIR/*.jpg' (quoted).
    #[cfg_attr(feature = "cli", arg(long))]
    pub images: String,
    /// Inner corners of the board, COLSxROWS (OpenCV's pattern size, e.g. 9x6).
    #[cfg_attr(feature = "cli", arg(long))]
    pub board: String,
    /// Square side, metres.
    #[cfg_attr(feature = "cli", arg(long))]
    pub square: f64,
    /// Distortion terms estimated: k1, k1k2, k1k2k3 or k1k2p1p2k3 (OpenCV's default).
    #[cfg_attr(feature = "cli", arg(long, default_value = "k1k2"))]
    pub model: DistortionModel,
    /// Hold fy = fx.
    #[cfg_attr(feature = "cli", arg(long))]
    pub fix_aspect: bool,
    /// The camera and the per-view report (JSON).
    #[cfg_attr(feature = "cli", arg(long))]
    pub out: PathBuf,
    /// Also write the camera in OpenCV's file layout (YAML for cv::FileStorage).
    #[cfg_attr(feature = "cli", arg(long))]
    pub opencv: Option<PathBuf>,
    /// Directory of the photos with their corners drawn (default: beside --out, `corners/`).
    #[cfg_attr(feature = "cli", arg(long))]
    pub corners_dir: Option<PathBuf>,
}

/// What [`IntrinsicsJob::run`] found and wrote.
#[derive(Debug, Clone, Serialize)]
pub struct IntrinsicsReport {
    /// The calibration (camera, per-view report), as written to the JSON file.
    pub calibration: PhotoCalibration,
    /// Files written: the JSON report, the OpenCV file when asked for.
    pub written: Vec<PathBuf>,
    /// The folder of corner drawings and how many were drawn.
    pub corner_drawings: (PathBuf, usize),
}

impl fmt::Display for IntrinsicsReport {
    /// The files written, each view's RMS or why it was rejected, the camera and the overall
    /// reprojection error.
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        for p in &self.written {
            writeln!(f, "wrote {}", p.display())?;
        }
        let (dir, n) = &self.corner_drawings;
        writeln!(f, "wrote {n} corner drawings to {}", dir.display())?;
        let cal = &self.calibration;
        for v in &cal.views {
            match &v.status {
                ViewStatus::Used { rms_point_px, .. } => {
                    writeln!(f, "  {}: RMS {rms_point_px:.4} px", v.path.display())?
                }
                other => writeln!(f, "  {}: rejected, {other:?}", v.path.display())?,
            }
        }
        let c = &cal.camera;
        writeln!(
            f,
            "{} of {} views; fx {:.4} fy {:.4} cx {:.4} cy {:.4}; distortion {:?}",
            cal.views_used,
            cal.views.len(),
            c.fx,
            c.fy,
            c.cx,
            c.cy,
            c.distortion()
        )?;
        write!(
            f,
            "reprojection RMS: {:.4} px per point ({:.4} px per coordinate)",
            cal.rms_point_px, cal.rms_px
        )
    }
}

/// Creates the folder a file goes in.
fn create_parent(path: &Path) -> CalibResult<()> {
    match path.parent().filter(|d| !d.as_os_str().is_empty()) {
        Some(d) => std::fs::create_dir_all(d).map_err(crate::io::io_err(d)),
        None => Ok(()),
    }
}

impl IntrinsicsJob {
    /// Detects the board in every photograph, calibrates the camera and writes the report, the
    /// OpenCV file and the corner drawings.
    pub fn run(&self) -> CalibResult<IntrinsicsReport> {
        let (cols, rows) = crate::session::parse_grid(&self.board)?;
        if !(self.square.is_finite() && self.square > 0.0) {
            return Err(CalibError::Invalid(format!(
                "square side {} m: expected a positive length",
                self.square
            )));
        }
        let board = BoardGeometry::from_inner_corners(cols, rows, self.square);
        let mut options = PhotoOptions::new(board);
        options.intrinsics.model = self.model;
        options.intrinsics.fix_aspect = self.fix_aspect;
        let paths = crate::session::glob_files(&self.images)?;
        let (calibration, _) = calibrate_photos(&paths, &options)?;
        let mut written = vec![self.out.clone()];
        create_parent(&self.out)?;
        calibration.write(&self.out)?;
        if let Some(p) = &self.opencv {
            create_parent(p)?;
            calibration.to_opencv().write(p)?;
            written.push(p.clone());
        }
        let dir = self
            .corners_dir
            .clone()
            .unwrap_or_else(|| self.out.parent().unwrap_or(Path::new(".")).join("corners"));
        let drawn = write_corner_drawings(&calibration, &dir)?;
        Ok(IntrinsicsReport {
            calibration,
            written,
            corner_drawings: (dir, drawn.len()),
        })
    }
}
