//! Camera intrinsics after Zhang (2000): homographies of a planar target, closed-form
//! initialisation, Levenberg–Marquardt refinement of fx, fy, cx, cy, the distortion terms of
//! the chosen [`DistortionModel`] and the board poses.

pub use crate::board::BoardGeometry;
use crate::error::{check_finite, CalibError, CalibResult};
use crate::geom::{
    apply_homography, homography, nearest_rotation, rotation_from_vector, vector_from_rotation,
};
use crate::lm::minimise;
use gantry_hal::CameraIntrinsics;
use nalgebra::{DMatrix, DVector, Matrix3, Vector3};
use serde::{Deserialize, Serialize};

/// Pose of a target: p_cam = R(rotation)·p_target + translation, rotation as axis-angle vector.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct BoardPose {
    /// Axis-angle rotation vector, radians.
    pub rotation: [f64; 3],
    /// Translation, metres.
    pub translation: [f64; 3],
}

impl BoardPose {
    /// Rotation matrix.
    pub fn rotation_matrix(&self) -> Matrix3<f64> {
        rotation_from_vector(&Vector3::from(self.rotation))
    }
}

/// Which Brown–Conrady terms the intrinsic fit estimates; the others are held at 0.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize, Deserialize, Hash)]
#[serde(rename_all = "snake_case")]
pub enum DistortionModel {
    /// k1 only: the gantry's default. With its narrow field of view (r² < 0.005 at the image
    /// corners) k2·r⁴ is far below the corner noise and a free k2 trades off against k1.
    #[default]
    K1,
    /// k1 and k2 (OpenCV's `CALIB_FIX_K3 | CALIB_ZERO_TANGENT_DIST`).
    K1K2,
    /// k1, k2 and k3 (OpenCV's `CALIB_ZERO_TANGENT_DIST`).
    K1K2K3,
    /// All five terms, OpenCV's default model.
    K1K2P1P2K3,
}

impl DistortionModel {
    /// Which of (k1, k2, p1, p2, k3) are estimated.
    pub fn free_terms(self) -> [bool; 5] {
        match self {
            Self::K1 => [true, false, false, false, false],
            Self::K1K2 => [true, true, false, false, false],
            Self::K1K2K3 => [true, true, false, false, true],
            Self::K1K2P1P2K3 => [true; 5],
        }
    }

    /// The name used on the command line and in files (`k1`, `k1k2`, `k1k2k3`, `k1k2p1p2k3`).
    pub fn name(self) -> &'static str {
        match self {
            Self::K1 => "k1",
            Self::K1K2 => "k1k2",
            Self::K1K2K3 => "k1k2k3",
            Self::K1K2P1P2K3 => "k1k2p1p2k3",
        }
    }
}

impl std::str::FromStr for DistortionModel {
    type Err = CalibError;
    fn from_str(s: &str) -> CalibResult<Self> {
        [Self::K1, Self::K1K2, Self::K1K2K3, Self::K1K2P1P2K3]
            .into_iter()
            .find(|m| m.name() == s)
            .ok_or_else(|| {
                CalibError::Invalid(format!(
                    "distortion model `{s}` (k1, k1k2, k1k2k3 or k1k2p1p2k3)"
                ))
            })
    }
}

/// Options of the intrinsic fit.
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize, Deserialize)]
pub struct IntrinsicOptions {
    /// The distortion terms estimated.
    #[serde(default)]
    pub model: DistortionModel,
    /// Hold fy = fx (square pixels; OpenCV's `CALIB_FIX_ASPECT_RATIO` with aspect 1).
    #[serde(default)]
    pub fix_aspect: bool,
}

/// Result of the intrinsic calibration.
#[derive(Debug, Clone, PartialEq)]
pub struct IntrinsicFit {
    /// The camera.
    pub camera: CameraIntrinsics,
    /// Pose of the board in each view.
    pub board_poses: Vec<BoardPose>,
    /// RMS reprojection error over all corners, pixels per coordinate.
    pub rms_px: f64,
    /// RMS reprojection distance over all corners, pixels per point (√2 × `rms_px`: the
    /// figure OpenCV's `calibrateCamera` returns).
    pub rms_point_px: f64,
    /// RMS reprojection error per view, pixels per coordinate.
    pub view_rms_px: Vec<f64>,
    /// The closed-form camera before refinement (distortion 0).
    pub initial: CameraIntrinsics,
}

/// Zhang's v_ij row of the constraint system on B = K⁻ᵀK⁻¹.
fn v_row(h: &Matrix3<f64>, i: usize, j: usize) -> [f64; 6] {
    let hi = h.column(i);
    let hj = h.column(j);
    [
        hi[0] * hj[0],
        hi[0] * hj[1] + hi[1] * hj[0],
        hi[1] * hj[1],
        hi[2] * hj[0] + hi[0] * hj[2],
        hi[2] * hj[1] + hi[1] * hj[2],
        hi[2] * hj[2],
    ]
}

/// Closed-form (fx, fy, cx, cy) from homographies, zero skew imposed. `None` if B is not
/// positive definite (noise or degenerate views).
fn closed_form(hs: &[Matrix3<f64>]) -> Option<(f64, f64, f64, f64)> {
    let mut v = DMatrix::zeros(2 * hs.len() + 1, 6);
    for (k, h) in hs.iter().enumerate() {
        let a = v_row(h, 0, 1);
        let b = v_row(h, 0, 0);
        let c = v_row(h, 1, 1);
        for j in 0..6 {
            v[(2 * k, j)] = a[j];
            v[(2 * k + 1, j)] = b[j] - c[j];
        }
    }
    // Zero skew: B12 = 0.
    let last = 2 * hs.len();
    let w = v.rows(0, last).abs().max().max(1e-300);
    v[(last, 1)] = w;
    let b = crate::geom::null_vector(&v);
    let (b11, b12, b22, b13, b23, b33) = (b[0], b[1], b[2], b[3], b[4], b[5]);
    let den = b11 * b22 - b12 * b12;
    let v0 = (b12 * b13 - b11 * b23) / den;
    let lambda = b33 - (b13 * b13 + v0 * (b12 * b13 - b11 * b23)) / b11;
    let alpha2 = lambda / b11;
    let beta2 = lambda * b11 / den;
    if !(alpha2 > 0.0 && beta2 > 0.0) {
        return None;
    }
    let alpha = alpha2.sqrt();
    let beta = beta2.sqrt();
    let gamma = -b12 * alpha * alpha * beta / lambda;
    let u0 = gamma * v0 / beta - b13 * alpha * alpha / lambda;
    let out = (alpha, beta, u0, v0);
    [alpha, beta, u0, v0]
        .iter()
        .all(|x| x.is_finite())
        .then_some(out)
}

/// Focal length (fx = fy) from homographies with the principal point held at (`cx`, `cy`).
fn focal_with_principal_point(hs: &[Matrix3<f64>], cx: f64, cy: f64) -> Option<f64> {
    // H' = T⁻¹H with T the principal-point shift; ω = diag(s, s, 1), s = 1/f².
    let t_inv = Matrix3::new(1.0, 0.0, -cx, 0.0, 1.0, -cy, 0.0, 0.0, 1.0);
    let (mut num, mut den) = (0.0, 0.0);
    for h in hs {
        let h = t_inv * h;
        let (h1, h2) = (h.column(0), h.column(1));
        // s·(h1x h2x + h1y h2y) + h1z h2z = 0
        let a1 = h1[0] * h2[0] + h1[1] * h2[1];
        let b1 = -h1[2] * h2[2];
        // s·(|h1xy|² − |h2xy|²) + (h1z² − h2z²) = 0
        let a2 = h1[0] * h1[0] + h1[1] * h1[1] - h2[0] * h2[0] - h2[1] * h2[1];
        let b2 = -(h1[2] * h1[2] - h2[2] * h2[2]);
        num += a1 * b1 + a2 * b2;
        den += a1 * a1 + a2 * a2;
    }
    let s = num / den;
    (s > 0.0 && s.is_finite()).then(|| 1.0 / s.sqrt())
}

/// Board pose from a homography and the camera matrix.
fn pose_from_homography(
    k: &Matrix3<f64>,
    h: &Matrix3<f64>,
) -> Option<(Matrix3<f64>, Vector3<f64>)> {
    let kinv = k.try_inverse()?;
    let m = kinv * h;
    let mut lambda = 1.0 / m.column(0).norm();
    if m[(2, 2)] * lambda < 0.0 {
        lambda = -lambda;
    }
    let r1 = m.column(0) * lambda;
    let r2 = m.column(1) * lambda;
    let r3 = r1.cross(&r2);
    let r = nearest_rotation(&Matrix3::from_columns(&[
        r1.into_owned(),
        r2.into_owned(),
        r3,
    ]));
    let t = m.column(2) * lambda;
    Some((r, t.into_owned()))
}

/// Calibrates the camera from corner lists of ≥ 3 views of `board` (each list in
/// [`BoardGeometry::inner_corners`] order), for a sensor of `width × height` pixels.
///
/// # Examples
///
/// ```
/// use calib::{fit_intrinsics, BoardGeometry, CameraIntrinsics, IntrinsicOptions};
/// use nalgebra::{Rotation3, Vector3};
/// // The true camera, and four poses of a 9 × 7-square board of 2 cm squares 35 cm away.
/// let truth = CameraIntrinsics {
///     width: 640, height: 480, fx: 800.0, fy: 805.0, cx: 322.0, cy: 236.0,
///     k1: -0.2, k2: 0.0, p1: 0.0, p2: 0.0, k3: 0.0,
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
/// // Exact corner pixels of every view, in inner-corner order.
/// let views: Vec<Vec<[f64; 2]>> = poses
///     .iter()
///     .map(|(r, t)| {
///         let corner = |p: &[f64; 2]| r * Vector3::new(p[0], p[1], 0.0) + t;
///         board.inner_corners().iter().map(|p| truth.project_camera_point(&corner(p)).unwrap()).collect()
///     })
///     .collect();
/// let fit = fit_intrinsics(&board, &views, 640, 480, &IntrinsicOptions::default()).unwrap();
/// // Zhang's method recovers the camera and its radial distortion from noise-free corners.
/// let c = fit.camera;
/// assert!((c.fx / truth.fx - 1.0).abs() < 1e-6 && (c.fy / truth.fy - 1.0).abs() < 1e-6);
/// assert!((c.cx - truth.cx).abs() < 1e-3 && (c.cy - truth.cy).abs() < 1e-3);
/// assert!((c.k1 - truth.k1).abs() < 1e-6);
/// assert!(fit.rms_px < 1e-6 && fit.board_poses.len() == 4);
/// // Each board pose comes back too (its distance from the camera, 35 cm at the centre).
/// let t = fit.board_poses[0].translation;
/// let centre_depth = (fit.board_poses[0].rotation_matrix() * centre).z + t[2];
/// assert!((centre_depth - 0.35).abs() < 1e-6);
/// ```
pub fn fit_intrinsics(
    board: &BoardGeometry,
    views: &[Vec<[f64; 2]>],
    width: usize,
    height: usize,
    options: &IntrinsicOptions,
) -> CalibResult<IntrinsicFit> {
    board.validate()?;
    if views.len() < 3 {
        return Err(CalibError::TooFewPoints {
            what: "checkerboard views",
            got: views.len(),
            need: 3,
        });
    }
    if width == 0 || height == 0 {
        return Err(CalibError::Invalid(format!("sensor {width}x{height}")));
    }
    let model = board.inner_corners();
    for v in views {
        if v.len() != model.len() {
            return Err(CalibError::Invalid(format!(
                "view with {} corners, the board has {}",
                v.len(),
                model.len()
            )));
        }
        for p in v {
            check_finite("checkerboard corners", p)?;
        }
    }
    // Homographies, refined on the geometric error.
    let mut hs = Vec::with_capacity(views.len());
    for v in views {
        let h0 = homography(&model, v)?;
        let start = DVector::from_iterator(9, h0.iter().copied());
        let steps = vec![1e-9; 9];
        let fit = minimise("homography", start, &steps, |x| {
            let h = Matrix3::from_column_slice(x.as_slice());
            let mut r = DVector::zeros(2 * v.len() + 1);
            for (k, (m, p)) in model.iter().zip(v).enumerate() {
                let q = apply_homography(&h, m);
                r[2 * k] = q[0] - p[0];
                r[2 * k + 1] = q[1] - p[1];
            }
            // Gauge: keep ‖H‖ = 1.
            r[2 * v.len()] = h.norm() - 1.0;
            Some(r)
        })?;
        hs.push(Matrix3::from_column_slice(fit.params.as_slice()));
    }
    let mut distinct: Vec<&Matrix3<f64>> = Vec::new();
    for hm in &hs {
        if distinct.iter().all(|d| (*d - hm).norm() > 1e-6) {
            distinct.push(hm);
        }
    }
    if distinct.len() < 2 {
        return Err(CalibError::Degenerate(
            "all checkerboard views show the board in the same pose".into(),
        ));
    }
    let (w, h) = (width as f64, height as f64);
    let centre = (0.5 * (w - 1.0), 0.5 * (h - 1.0));
    let plausible = |fx: f64, fy: f64, cx: f64, cy: f64| {
        fx > 0.0
            && fy > 0.0
            && (fx / fy - 1.0).abs() < 0.2
            && cx > -0.25 * w
            && cx < 1.25 * w
            && cy > -0.25 * h
            && cy < 1.25 * h
    };
    let (fx, fy, cx, cy) = match closed_form(&hs) {
        Some((fx, fy, cx, cy)) if plausible(fx, fy, cx, cy) => (fx, fy, cx, cy),
        other => {
            tracing::debug!(?other, "closed form implausible; principal point at centre");
            let f = focal_with_principal_point(&hs, centre.0, centre.1).ok_or_else(|| {
                CalibError::Degenerate(
                    "checkerboard views do not determine the focal length (too little tilt?)"
                        .into(),
                )
            })?;
            (f, f, centre.0, centre.1)
        }
    };
    let (fx, fy) = if options.fix_aspect {
        let f = (fx * fy).sqrt();
        (f, f)
    } else {
        (fx, fy)
    };
    let initial = CameraIntrinsics::radial(width, height, fx, fy, cx, cy, 0.0, 0.0);
    let kmat = Matrix3::new(fx, 0.0, cx, 0.0, fy, cy, 0.0, 0.0, 1.0);
    let nk = 9;
    let mut start = DVector::zeros(nk + 6 * views.len());
    start[0] = fx;
    start[1] = fy;
    start[2] = cx;
    start[3] = cy;
    for (i, hm) in hs.iter().enumerate() {
        let (r, t) = pose_from_homography(&kmat, hm).ok_or_else(|| {
            CalibError::Degenerate("singular camera matrix from the closed form".into())
        })?;
        start
            .rows_mut(nk + 6 * i, 3)
            .copy_from(&vector_from_rotation(&r));
        start.rows_mut(nk + 6 * i + 3, 3).copy_from(&t);
    }
    let mut steps = vec![
        fx * 1e-7,
        fy * 1e-7,
        1e-4,
        1e-4,
        1e-6,
        1e-6,
        1e-7,
        1e-7,
        1e-6,
    ];
    for i in 0..views.len() {
        steps.extend([1e-7; 3]);
        let tn = start.rows(nk + 6 * i + 3, 3).norm().max(1e-3);
        steps.extend([tn * 1e-7; 3]);
    }
    let free = options.model.free_terms();
    let fix_aspect = options.fix_aspect;
    let n_corners: usize = views.iter().map(|v| v.len()).sum();
    let camera_of = |x: &DVector<f64>| {
        let term = |k: usize| if free[k] { x[4 + k] } else { 0.0 };
        CameraIntrinsics {
            width,
            height,
            fx: x[0],
            fy: if fix_aspect { x[0] } else { x[1] },
            cx: x[2],
            cy: x[3],
            k1: term(0),
            k2: term(1),
            p1: term(2),
            p2: term(3),
            k3: term(4),
        }
    };
    let held: Vec<usize> = (0..5)
        .filter(|&k| !free[k])
        .map(|k| 4 + k)
        .chain(fix_aspect.then_some(1))
        .collect();
    let residual = |x: &DVector<f64>| -> Option<DVector<f64>> {
        let cam = camera_of(x);
        let mut out = DVector::zeros(2 * n_corners + held.len());
        let mut k = 0;
        for (i, v) in views.iter().enumerate() {
            let o = nk + 6 * i;
            let r = rotation_from_vector(&Vector3::new(x[o], x[o + 1], x[o + 2]));
            let t = Vector3::new(x[o + 3], x[o + 4], x[o + 5]);
            for (m, p) in model.iter().zip(v) {
                let q = cam.project_camera_point(&(r * Vector3::new(m[0], m[1], 0.0) + t))?;
                out[k] = q[0] - p[0];
                out[k + 1] = q[1] - p[1];
                k += 2;
            }
        }
        // Held parameters are pulled to zero (keeps their Jacobian columns non-zero).
        for (j, &h) in held.iter().enumerate() {
            out[k + j] = x[h] - if h == 1 { x[0] } else { 0.0 };
        }
        Some(out)
    };
    let fit = minimise("camera intrinsics", start, &steps, residual)?;
    let x = &fit.params;
    let camera = camera_of(x);
    camera.validate()?;
    let board_poses: Vec<BoardPose> = (0..views.len())
        .map(|i| {
            let o = nk + 6 * i;
            BoardPose {
                rotation: [x[o], x[o + 1], x[o + 2]],
                translation: [x[o + 3], x[o + 4], x[o + 5]],
            }
        })
        .collect();
    let mut view_rms_px = Vec::with_capacity(views.len());
    let mut k = 0;
    let mut total = 0.0;
    for v in views {
        let e: f64 = fit.residuals.rows(k, 2 * v.len()).norm_squared();
        total += e;
        view_rms_px.push((e / (2 * v.len()) as f64).sqrt());
        k += 2 * v.len();
    }
    let rms_px = (total / (2 * n_corners) as f64).sqrt();
    Ok(IntrinsicFit {
        camera,
        board_poses,
        rms_px,
        rms_point_px: (total / n_corners as f64).sqrt(),
        view_rms_px,
        initial,
    })
}
