//! Camera pose from digitizer-tip correspondences (thesis §3.2): linear initialisation (DLT on
//! undistorted normalised coordinates, or a plane homography for coplanar tips), then
//! Levenberg–Marquardt on the reprojection error.

use crate::error::{check_finite, CalibError, CalibResult};
use crate::geom::{
    check_not_collinear, homography, nearest_rotation, null_vector, point_spread,
    rotation_from_vector, vector_from_rotation,
};
use crate::lm::minimise;
use gantry_hal::{CameraIntrinsics, CameraPose, Point3};
use nalgebra::{DMatrix, DVector, Matrix3, Matrix3x4, Vector3, Vector4};
use serde::{Deserialize, Serialize};

/// A digitizer-tip position and where the tip appears in the image.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct TipCorrespondence {
    /// Tip position as the digitizer reports it, world metres.
    pub world: Point3,
    /// Tip position in the image, pixels.
    pub pixel: [f64; 2],
}

/// Fitted camera pose and its residual.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ExtrinsicFit {
    /// World-to-camera transform.
    pub pose: CameraPose,
    /// RMS reprojection error of the tips, pixels per coordinate.
    pub rms_px: f64,
}

/// Estimates the world-to-camera pose from ≥ 6 tip correspondences with known intrinsics.
pub fn fit_extrinsics(
    camera: &CameraIntrinsics,
    tips: &[TipCorrespondence],
) -> CalibResult<ExtrinsicFit> {
    camera.validate()?;
    if tips.len() < 6 {
        return Err(CalibError::TooFewPoints {
            what: "digitizer tip correspondences",
            got: tips.len(),
            need: 6,
        });
    }
    for t in tips {
        check_finite("digitizer tip correspondences", &t.world)?;
        check_finite("digitizer tip correspondences", &t.pixel)?;
    }
    let world: Vec<Vector3<f64>> = tips.iter().map(|t| Vector3::from(t.world)).collect();
    let norm: Vec<[f64; 2]> = tips
        .iter()
        .map(|t| {
            let (x, y) = camera.normalised(t.pixel[0], t.pixel[1]);
            [x, y]
        })
        .collect();
    let spread = point_spread(&world);
    check_not_collinear("digitizer tips", &spread)?;
    let (r0, t0) = if spread.singular[2] < 1e-4 * spread.singular[0] {
        planar_init(&world, &norm, &spread)?
    } else {
        dlt_init(&world, &norm)?
    };
    let mut start = DVector::zeros(6);
    start.rows_mut(0, 3).copy_from(&vector_from_rotation(&r0));
    start.rows_mut(3, 3).copy_from(&t0);
    let scale = t0.norm().max(1e-3);
    let mut steps = vec![1e-7; 3];
    steps.extend([scale * 1e-7; 3]);
    let residual = |x: &DVector<f64>| -> Option<DVector<f64>> {
        let r = rotation_from_vector(&Vector3::new(x[0], x[1], x[2]));
        let t = Vector3::new(x[3], x[4], x[5]);
        let mut out = DVector::zeros(2 * tips.len());
        for (k, (p, tip)) in world.iter().zip(tips).enumerate() {
            let px = camera.project_camera_point(&(r * p + t))?;
            out[2 * k] = px[0] - tip.pixel[0];
            out[2 * k + 1] = px[1] - tip.pixel[1];
        }
        Some(out)
    };
    let fit = minimise("camera extrinsics", start, &steps, residual)?;
    let x = &fit.params;
    let r = rotation_from_vector(&Vector3::new(x[0], x[1], x[2]));
    let t = Vector3::new(x[3], x[4], x[5]);
    Ok(ExtrinsicFit {
        pose: CameraPose::from_matrix(&r, &t),
        rms_px: fit.rms(),
    })
}

/// DLT for P = λ[R | t] on normalised image coordinates (Hartley-normalised world points).
fn dlt_init(
    world: &[Vector3<f64>],
    norm: &[[f64; 2]],
) -> CalibResult<(Matrix3<f64>, Vector3<f64>)> {
    let n = world.len() as f64;
    let c = world.iter().fold(Vector3::zeros(), |a, p| a + p) / n;
    let md = world.iter().map(|p| (p - c).norm()).sum::<f64>() / n;
    let s = 3f64.sqrt() / md;
    // World normalisation T_w (4×4) and image normalisation T_i (3×3).
    let mut tw = nalgebra::Matrix4::identity() * s;
    tw[(3, 3)] = 1.0;
    tw.fixed_view_mut::<3, 1>(0, 3).copy_from(&(-s * c));
    let ti = crate::geom::normalising_transform(norm);
    let mut a = DMatrix::zeros(2 * world.len(), 12);
    for (k, (p, q)) in world.iter().zip(norm).enumerate() {
        let pw = tw * Vector4::new(p.x, p.y, p.z, 1.0);
        let qi = ti * Vector3::new(q[0], q[1], 1.0);
        let (u, v) = (qi.x / qi.z, qi.y / qi.z);
        for j in 0..4 {
            a[(2 * k, j)] = pw[j];
            a[(2 * k, 8 + j)] = -u * pw[j];
            a[(2 * k + 1, 4 + j)] = pw[j];
            a[(2 * k + 1, 8 + j)] = -v * pw[j];
        }
    }
    let p = null_vector(&a);
    let pn = Matrix3x4::from_row_slice(p.as_slice());
    let ti_inv = ti
        .try_inverse()
        .ok_or_else(|| CalibError::Degenerate("digitizer tips: image points coincide".into()))?;
    let mut pm = ti_inv * pn * tw;
    let mut m: Matrix3<f64> = pm.fixed_view::<3, 3>(0, 0).into_owned();
    if m.determinant() < 0.0 {
        pm = -pm;
        m = -m;
    }
    let sv = m.singular_values();
    let lambda = sv.mean();
    if !(lambda > 0.0) || !lambda.is_finite() {
        return Err(CalibError::Degenerate(
            "digitizer tips: singular projection".into(),
        ));
    }
    let r = nearest_rotation(&m);
    let t = pm.column(3) / lambda;
    Ok((r, t.into_owned()))
}

/// Coplanar tips: homography from in-plane coordinates to normalised image coordinates.
fn planar_init(
    world: &[Vector3<f64>],
    norm: &[[f64; 2]],
    spread: &crate::geom::PointSpread,
) -> CalibResult<(Matrix3<f64>, Vector3<f64>)> {
    let (e1, e2) = (spread.axes[0], spread.axes[1]);
    let e3 = e1.cross(&e2);
    let o = spread.centroid;
    let plane: Vec<[f64; 2]> = world
        .iter()
        .map(|p| [(p - o).dot(&e1), (p - o).dot(&e2)])
        .collect();
    let h = homography(&plane, norm)?;
    let (h1, h2, h3) = (h.column(0), h.column(1), h.column(2));
    let mut lambda = 1.0 / h1.norm();
    if h3.z * lambda < 0.0 {
        lambda = -lambda;
    }
    let r1 = h1 * lambda;
    let r2 = h2 * lambda;
    let rp = nearest_rotation(&Matrix3::from_columns(&[
        r1.into_owned(),
        r2.into_owned(),
        r1.cross(&r2),
    ]));
    let tp = h3 * lambda;
    // Plane frame → world: p = o + [e1 e2 e3] q, so R_world = R_plane · [e1 e2 e3]ᵀ.
    let b = Matrix3::from_columns(&[e1, e2, e3]);
    let r = rp * b.transpose();
    let t = tp - r * o;
    Ok((r, t))
}
