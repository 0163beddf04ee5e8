//! A camera calibrated from a folder of checkerboard photographs alone (PNG, JPEG or TIFF;
//! 8 or 16 bit; grey or colour), without the digitizer or the rig: corners in every photo,
//! views rejected with their reason, Zhang's fit with the chosen distortion model, per-view
//! reprojection RMS, and the corners drawn on each image.

use crate::board::BoardGeometry;
use crate::corners::{detect_board_gray, CornerOptions, GrayImage};
use crate::error::{CalibError, CalibResult};
use crate::intrinsics::{fit_intrinsics, IntrinsicFit, IntrinsicOptions};
use gantry_hal::CameraIntrinsics;
use serde::{Deserialize, Serialize};
use std::path::{Path, PathBuf};

/// Reads an image file as a grey image in [0, 1].
pub fn load_photo(path: &Path) -> CalibResult<GrayImage> {
    let bytes = std::fs::read(path).map_err(crate::io::io_err(path))?;
    let img = image::load_from_memory(&bytes).map_err(|e| CalibError::Parse {
        path: path.to_path_buf(),
        detail: e.to_string(),
    })?;
    Ok(GrayImage::from_dynamic(&img))
}

/// Settings of [`calibrate_photos`].
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct PhotoOptions {
    /// The checkerboard.
    pub board: BoardGeometry,
    /// Corner detector settings.
    pub corners: CornerOptions,
    /// Intrinsic fit settings (distortion model, fixed aspect).
    pub intrinsics: IntrinsicOptions,
    /// Views whose edges are blurred over more than this fraction of a square (Gaussian σ of
    /// the edge profile) are rejected.
    pub max_blur_fraction: f64,
    /// Fewest usable views.
    pub min_views: usize,
}

impl PhotoOptions {
    /// Defaults for `board`: OpenCV-like two-term radial model, blur limit 0.15 squares, 3
    /// views at least.
    pub fn new(board: BoardGeometry) -> Self {
        Self {
            board,
            corners: CornerOptions::default(),
            intrinsics: IntrinsicOptions::default(),
            max_blur_fraction: 0.15,
            min_views: 3,
        }
    }
}

/// What happened to one photograph.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case", tag = "status")]
pub enum ViewStatus {
    /// Used in the fit.
    Used {
        /// Reprojection RMS, pixels per coordinate.
        rms_px: f64,
        /// Reprojection RMS, pixels per point (OpenCV's figure).
        rms_point_px: f64,
        /// Edge blur, Gaussian σ in pixels.
        blur_px: f64,
    },
    /// The board was not found.
    BoardNotFound {
        /// What failed.
        reason: String,
    },
    /// Part of the board was found, not all of it.
    TooFewCorners {
        /// What failed.
        reason: String,
    },
    /// The board is too blurred for accurate corners.
    Blur {
        /// Edge blur, Gaussian σ in pixels.
        blur_px: f64,
        /// The limit, pixels.
        limit_px: f64,
    },
}

/// One photograph's report.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ViewReport {
    /// The file.
    pub path: PathBuf,
    /// Its fate.
    #[serde(flatten)]
    pub status: ViewStatus,
    /// Detected corners (in [`BoardGeometry::inner_corners`] order), when found.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub corners: Option<Vec<[f64; 2]>>,
}

/// A camera calibrated from photographs (the `camera.json` of `gantry calibrate intrinsics`).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct PhotoCalibration {
    /// The camera.
    pub camera: CameraIntrinsics,
    /// Settings used.
    pub options: PhotoOptions,
    /// Reprojection RMS over all corners, pixels per coordinate.
    pub rms_px: f64,
    /// Reprojection RMS over all corners, pixels per point (OpenCV's `calibrateCamera` figure).
    pub rms_point_px: f64,
    /// Views used.
    pub views_used: usize,
    /// Every photograph, in input order.
    pub views: Vec<ViewReport>,
}

impl PhotoCalibration {
    /// The camera in OpenCV's file layout.
    pub fn to_opencv(&self) -> crate::opencv::OpenCvCamera {
        crate::opencv::OpenCvCamera {
            camera: self.camera,
            frames: self.views_used,
            avg_reprojection_error: self.rms_point_px,
        }
    }

    /// Writes the report as pretty JSON, atomically.
    pub fn write(&self, path: &Path) -> CalibResult<()> {
        let mut text = serde_json::to_string_pretty(self)?;
        text.push('\n');
        crate::io::write_atomic(path, text.as_bytes())
    }
}

/// Edge blur of a detected board: median over the square edges between neighbouring corners
/// of the Gaussian σ of the edge profile (step / (√(2π) · steepest slope)), pixels.
pub fn edge_blur(img: &GrayImage, board: &BoardGeometry, corners: &[[f64; 2]]) -> f64 {
    let (nx, ny) = (board.corners_x(), board.corners_y());
    let mut sigmas = Vec::new();
    let mut edge = |p: [f64; 2], q: [f64; 2]| {
        let m = [0.5 * (p[0] + q[0]), 0.5 * (p[1] + q[1])];
        let (dx, dy) = (q[0] - p[0], q[1] - p[1]);
        let len = dx.hypot(dy);
        if len < 4.0 {
            return;
        }
        let n = [-dy / len, dx / len];
        let half = 0.3 * len;
        let step = 0.25;
        let k = (half / step) as i32;
        let vals: Vec<f64> = (-k..=k)
            .map(|i| {
                let t = i as f64 * step;
                img.sample(m[0] + t * n[0], m[1] + t * n[1])
            })
            .collect();
        let contrast = (vals[vals.len() - 1] - vals[0]).abs();
        let slope = vals
            .windows(3)
            .map(|w| (w[2] - w[0]).abs() / (2.0 * step))
            .fold(0.0, f64::max);
        if contrast > 0.0 && slope > 0.0 {
            sigmas.push(contrast / (slope * (std::f64::consts::TAU).sqrt()));
        }
    };
    for j in 0..ny {
        for i in 0..nx {
            let p = corners[j * nx + i];
            if i + 1 < nx {
                edge(p, corners[j * nx + i + 1]);
            }
            if j + 1 < ny {
                edge(p, corners[(j + 1) * nx + i]);
            }
        }
    }
    if sigmas.is_empty() {
        return f64::NAN;
    }
    sigmas.sort_by(f64::total_cmp);
    sigmas[sigmas.len() / 2]
}

/// Median distance between neighbouring corners, pixels.
fn square_px(board: &BoardGeometry, corners: &[[f64; 2]]) -> f64 {
    let nx = board.corners_x();
    let mut d: Vec<f64> = corners
        .windows(2)
        .enumerate()
        .filter(|(k, _)| (k + 1) % nx != 0)
        .map(|(_, w)| (w[1][0] - w[0][0]).hypot(w[1][1] - w[0][1]))
        .collect();
    if d.is_empty() {
        return f64::NAN;
    }
    d.sort_by(f64::total_cmp);
    d[d.len() / 2]
}

/// Detects the board in one photograph and classifies the outcome.
pub fn examine_photo(
    img: &GrayImage,
    options: &PhotoOptions,
    index: usize,
) -> (ViewStatus, Option<Vec<[f64; 2]>>) {
    match detect_board_gray(img, &options.board, &options.corners, index) {
        Ok(c) => {
            let blur = edge_blur(img, &options.board, &c);
            let limit = options.max_blur_fraction * square_px(&options.board, &c);
            if blur > limit {
                (
                    ViewStatus::Blur {
                        blur_px: blur,
                        limit_px: limit,
                    },
                    None,
                )
            } else {
                (
                    ViewStatus::Used {
                        rms_px: f64::NAN,
                        rms_point_px: f64::NAN,
                        blur_px: blur,
                    },
                    Some(c),
                )
            }
        }
        Err(CalibError::TooFewCorners { reason, .. }) => {
            (ViewStatus::TooFewCorners { reason }, None)
        }
        Err(e) => (
            ViewStatus::BoardNotFound {
                reason: e.to_string(),
            },
            None,
        ),
    }
}

/// Calibrates a camera from photographs of `options.board` (all of one size).
///
/// # Examples
///
/// Synthetic photographs stand in for real ones: each is a 640 × 480 image of the board seen
/// by a known pinhole camera, rendered with 2 × 2 samples per pixel and written as PNG.
///
/// ```
/// use calib::{calibrate_photos, BoardGeometry, CameraIntrinsics, PhotoOptions, ViewStatus};
/// use nalgebra::{Matrix3, Rotation3, Vector3};
/// // The true camera, and four poses of a 9 × 7-square board of 2 cm squares 35 cm away.
/// let truth = CameraIntrinsics {
///     width: 640, height: 480, fx: 800.0, fy: 805.0, cx: 322.0, cy: 236.0,
///     k1: 0.0, k2: 0.0, p1: 0.0, p2: 0.0, k3: 0.0,
/// };
/// let board = BoardGeometry { squares_x: 9, squares_y: 7, square_m: 0.02 };
/// let centre = Vector3::new(0.09, 0.07, 0.0);
/// let poses: Vec<(Rotation3<f64>, Vector3<f64>)> =
///     [(0.4, 0.0, 0.1), (-0.4, 0.2, 0.0), (0.0, 0.5, -0.2), (0.3, -0.4, 0.2)]
///         .iter()
///         .map(|&(a, b, c)| {
///             let r = Rotation3::from_euler_angles(a, b, c);
///             (r, Vector3::new(0.0, 0.0, 0.35) - r * centre)
///         })
///         .collect();
/// let dir = tempfile::tempdir().unwrap();
/// let mut paths = Vec::new();
/// let k = Matrix3::new(truth.fx, 0.0, truth.cx, 0.0, truth.fy, truth.cy, 0.0, 0.0, 1.0);
/// for (i, (r, t)) in poses.iter().enumerate() {
///     // Pixel → board plane (in squares) through the inverse of the board's homography.
///     let m = r.matrix();
///     let h = k * Matrix3::from_columns(&[m.column(0).into_owned(), m.column(1).into_owned(), *t]);
///     let to_board = h.try_inverse().unwrap();
///     let shade = |u: f64, v: f64| -> f64 {
///         let q = to_board * Vector3::new(u, v, 1.0);
///         let (x, y) = (q.x / q.z / 0.02, q.y / q.z / 0.02); // metres to squares
///         if x < -1.0 || y < -1.0 || x > 10.0 || y > 8.0 {
///             0.5 // background
///         } else if x < 0.0 || y < 0.0 || x >= 9.0 || y >= 7.0 {
///             0.95 // white margin around the squares
///         } else if (x.floor() + y.floor()) as i64 % 2 == 0 {
///             0.05
///         } else {
///             0.95
///         }
///     };
///     let img = image::GrayImage::from_fn(640, 480, |u, v| {
///         let (u, v) = (u as f64, v as f64);
///         let sum: f64 = [(-0.25, -0.25), (0.25, -0.25), (-0.25, 0.25), (0.25, 0.25)]
///             .iter()
///             .map(|(du, dv)| shade(u + du, v + dv))
///             .sum();
///         image::Luma([(255.0 * sum / 4.0).round() as u8])
///     });
///     let path = dir.path().join(format!("view{i}.png"));
///     img.save(&path).unwrap();
///     paths.push(path);
/// }
///
/// let (calibration, fit) = calibrate_photos(&paths, &PhotoOptions::new(board)).unwrap();
/// assert_eq!(calibration.views_used, 4);
/// assert!(calibration.views.iter().all(|v| matches!(v.status, ViewStatus::Used { .. })));
/// // Sub-pixel corners give the focal length to a fraction of a percent.
/// let c = calibration.camera;
/// assert!((c.fx / truth.fx - 1.0).abs() < 0.01 && (c.fy / truth.fy - 1.0).abs() < 0.01, "{c:?}");
/// assert!((c.cx - truth.cx).abs() < 3.0 && (c.cy - truth.cy).abs() < 3.0, "{c:?}");
/// assert!(calibration.rms_px < 0.1 && fit.rms_px == calibration.rms_px);
/// ```
pub fn calibrate_photos(
    paths: &[PathBuf],
    options: &PhotoOptions,
) -> CalibResult<(PhotoCalibration, IntrinsicFit)> {
    options.board.validate()?;
    let mut size = None;
    let mut views = Vec::with_capacity(paths.len());
    for (i, path) in paths.iter().enumerate() {
        let img = load_photo(path)?;
        match size {
            None => size = Some((img.width, img.height)),
            Some(s) if s != (img.width, img.height) => {
                return Err(CalibError::Invalid(format!(
                    "{} is {}x{}, the first photo {}x{}",
                    path.display(),
                    img.width,
                    img.height,
                    s.0,
                    s.1
                )))
            }
            _ => {}
        }
        let (status, corners) = examine_photo(&img, options, i);
        if !matches!(status, ViewStatus::Used { .. }) {
            tracing::warn!(photo = %path.display(), ?status, "view rejected");
        }
        views.push(ViewReport {
            path: path.clone(),
            status,
            corners,
        });
    }
    let (width, height) = size.ok_or(CalibError::TooFewPoints {
        what: "photographs",
        got: 0,
        need: options.min_views.max(3),
    })?;
    let used: Vec<Vec<[f64; 2]>> = views.iter().filter_map(|v| v.corners.clone()).collect();
    let need = options.min_views.max(3);
    if used.len() < need {
        return Err(CalibError::TooFewPoints {
            what: "photographs with the board found",
            got: used.len(),
            need,
        });
    }
    let fit = fit_intrinsics(&options.board, &used, width, height, &options.intrinsics)?;
    let mut k = 0;
    for v in views.iter_mut() {
        if let ViewStatus::Used {
            rms_px,
            rms_point_px,
            ..
        } = &mut v.status
        {
            *rms_px = fit.view_rms_px[k];
            *rms_point_px = fit.view_rms_px[k] * std::f64::consts::SQRT_2;
            k += 1;
        }
    }
    let cal = PhotoCalibration {
        camera: fit.camera,
        options: *options,
        rms_px: fit.rms_px,
        rms_point_px: fit.rms_point_px,
        views_used: used.len(),
        views,
    };
    Ok((cal, fit))
}

/// PNG bytes of a photograph with its corners drawn: small crosses, the first corner red, the
/// rest of the first row green, the others blue (so the labelling can be checked by eye).
pub fn draw_corners(img: &GrayImage, corners: &[[f64; 2]], row: usize) -> CalibResult<Vec<u8>> {
    let (w, h) = (img.width as u32, img.height as u32);
    let mut rgb = image::RgbImage::from_fn(w, h, |x, y| {
        let v = (img.data[(y * w + x) as usize].clamp(0.0, 1.0) * 255.0).round() as u8;
        image::Rgb([v, v, v])
    });
    for (k, p) in corners.iter().enumerate() {
        let colour = if k == 0 {
            [255, 0, 0]
        } else if k < row {
            [0, 200, 0]
        } else {
            [40, 90, 255]
        };
        let (cx, cy) = (p[0].round() as i64, p[1].round() as i64);
        for d in -4i64..=4 {
            for (x, y) in [(cx + d, cy), (cx, cy + d)] {
                if x >= 0 && y >= 0 && (x as u32) < w && (y as u32) < h {
                    rgb.put_pixel(x as u32, y as u32, image::Rgb(colour));
                }
            }
        }
    }
    let mut out = std::io::Cursor::new(Vec::new());
    image::DynamicImage::ImageRgb8(rgb).write_to(&mut out, image::ImageFormat::Png)?;
    Ok(out.into_inner())
}

/// Writes `DIR/<photo stem>.png` with the corners drawn, for every view in which the board was
/// found; returns the paths written.
pub fn write_corner_drawings(cal: &PhotoCalibration, dir: &Path) -> CalibResult<Vec<PathBuf>> {
    std::fs::create_dir_all(dir).map_err(crate::io::io_err(dir))?;
    let mut written = Vec::new();
    for v in &cal.views {
        let Some(c) = &v.corners else { continue };
        let img = load_photo(&v.path)?;
        let stem = v
            .path
            .file_stem()
            .map_or("view".into(), |s| s.to_string_lossy().into_owned());
        let p = dir.join(format!("{stem}.png"));
        crate::io::write_atomic(&p, &draw_corners(&img, c, cal.options.board.corners_x())?)?;
        written.push(p);
    }
    Ok(written)
}
