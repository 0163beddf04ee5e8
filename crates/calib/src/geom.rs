//! Small linear-algebra helpers: rotation vectors, nearest rotation, plane fits, homographies.

use crate::error::{CalibError, CalibResult};
use nalgebra::{DMatrix, Matrix3, Rotation3, Vector3};

/// Rotation matrix of an axis-angle vector (radians).
pub(crate) fn rotation_from_vector(r: &Vector3<f64>) -> Matrix3<f64> {
    Rotation3::new(*r).into_inner()
}

/// Axis-angle vector of a rotation matrix (assumed orthonormal).
pub(crate) fn vector_from_rotation(r: &Matrix3<f64>) -> Vector3<f64> {
    Rotation3::from_matrix_unchecked(*r).scaled_axis()
}

/// Rotation closest to `m` in the Frobenius norm (det = +1).
pub(crate) fn nearest_rotation(m: &Matrix3<f64>) -> Matrix3<f64> {
    let svd = m.svd(true, true);
    let u = svd.u.expect("u requested");
    let vt = svd.v_t.expect("v_t requested");
    let mut r = u * vt;
    if r.determinant() < 0.0 {
        let d = Matrix3::from_diagonal(&Vector3::new(1.0, 1.0, -1.0));
        r = u * d * vt;
    }
    r
}

/// Angle (radians) of the rotation taking `a` to `b`.
pub fn rotation_angle_between(a: &Matrix3<f64>, b: &Matrix3<f64>) -> f64 {
    let c = ((a.transpose() * b).trace() - 1.0) / 2.0;
    c.clamp(-1.0, 1.0).acos()
}

/// Centroid and singular values / right singular vectors of the centred point cloud.
pub(crate) struct PointSpread {
    pub centroid: Vector3<f64>,
    /// Singular values, descending.
    pub singular: [f64; 3],
    /// Matching unit directions.
    pub axes: [Vector3<f64>; 3],
}

pub(crate) fn point_spread(points: &[Vector3<f64>]) -> PointSpread {
    let n = points.len().max(1) as f64;
    let centroid = points.iter().fold(Vector3::zeros(), |a, p| a + p) / n;
    let mut cov = Matrix3::zeros();
    for p in points {
        let d = p - centroid;
        cov += d * d.transpose();
    }
    let eig = cov.symmetric_eigen();
    let mut idx = [0usize, 1, 2];
    idx.sort_by(|&a, &b| eig.eigenvalues[b].total_cmp(&eig.eigenvalues[a]));
    let singular = idx.map(|i| eig.eigenvalues[i].max(0.0).sqrt());
    let axes = idx.map(|i| eig.eigenvectors.column(i).into_owned());
    PointSpread {
        centroid,
        singular,
        axes,
    }
}

/// Fails for point clouds that are (nearly) a single point or a line.
pub(crate) fn check_not_collinear(what: &str, s: &PointSpread) -> CalibResult<()> {
    if !(s.singular[0] > 0.0) || s.singular[1] < 1e-7 * s.singular[0] {
        return Err(CalibError::Degenerate(format!(
            "{what}: points are collinear or coincide"
        )));
    }
    Ok(())
}

/// Null vector (right singular vector of the smallest singular value) of `a` (rows ≥ cols
/// is ensured by zero padding).
pub(crate) fn null_vector(a: &DMatrix<f64>) -> nalgebra::DVector<f64> {
    let n = a.ncols();
    let a = if a.nrows() < n {
        let mut p = DMatrix::zeros(n, n);
        p.view_mut((0, 0), (a.nrows(), n)).copy_from(a);
        p
    } else {
        a.clone()
    };
    // Eigen-decomposition of AᵀA is enough for these small, well-normalised systems.
    let ata = a.transpose() * &a;
    let eig = ata.symmetric_eigen();
    let (imin, _) = eig
        .eigenvalues
        .iter()
        .enumerate()
        .min_by(|a, b| a.1.total_cmp(b.1))
        .expect("non-empty");
    eig.eigenvectors.column(imin).into_owned()
}

/// Similarity normalising 2-D points to centroid 0 and mean distance √2 (Hartley).
pub(crate) fn normalising_transform(pts: &[[f64; 2]]) -> Matrix3<f64> {
    let n = pts.len().max(1) as f64;
    let (mx, my) = pts
        .iter()
        .fold((0.0, 0.0), |a, p| (a.0 + p[0] / n, a.1 + p[1] / n));
    let md = pts
        .iter()
        .map(|p| ((p[0] - mx).powi(2) + (p[1] - my).powi(2)).sqrt())
        .sum::<f64>()
        / n;
    let s = if md > 0.0 {
        std::f64::consts::SQRT_2 / md
    } else {
        1.0
    };
    Matrix3::new(s, 0.0, -s * mx, 0.0, s, -s * my, 0.0, 0.0, 1.0)
}

fn apply(h: &Matrix3<f64>, p: &[f64; 2]) -> [f64; 2] {
    let q = h * Vector3::new(p[0], p[1], 1.0);
    [q.x / q.z, q.y / q.z]
}

/// Homography mapping `src` to `dst` (normalised DLT), scaled to ‖H‖ = 1 with H[2,2] ≥ 0.
pub(crate) fn homography(src: &[[f64; 2]], dst: &[[f64; 2]]) -> CalibResult<Matrix3<f64>> {
    if src.len() != dst.len() || src.len() < 4 {
        return Err(CalibError::TooFewPoints {
            what: "homography correspondences",
            got: src.len().min(dst.len()),
            need: 4,
        });
    }
    let ts = normalising_transform(src);
    let td = normalising_transform(dst);
    let mut a = DMatrix::zeros(2 * src.len(), 9);
    for (k, (s, d)) in src.iter().zip(dst).enumerate() {
        let s = apply(&ts, s);
        let d = apply(&td, d);
        let (x, y, u, v) = (s[0], s[1], d[0], d[1]);
        let r0 = [-x, -y, -1.0, 0.0, 0.0, 0.0, u * x, u * y, u];
        let r1 = [0.0, 0.0, 0.0, -x, -y, -1.0, v * x, v * y, v];
        for j in 0..9 {
            a[(2 * k, j)] = r0[j];
            a[(2 * k + 1, j)] = r1[j];
        }
    }
    let h = null_vector(&a);
    let hn = Matrix3::new(h[0], h[1], h[2], h[3], h[4], h[5], h[6], h[7], h[8]);
    let td_inv = td
        .try_inverse()
        .ok_or_else(|| CalibError::Degenerate("image points coincide".into()))?;
    let mut hm = td_inv * hn * ts;
    let norm = hm.norm();
    if !(norm > 0.0) || !hm.iter().all(|v| v.is_finite()) {
        return Err(CalibError::Degenerate("homography is singular".into()));
    }
    hm /= norm;
    if hm[(2, 2)] < 0.0 {
        hm = -hm;
    }
    Ok(hm)
}

/// Applies a homography to a 2-D point.
pub(crate) fn apply_homography(h: &Matrix3<f64>, p: &[f64; 2]) -> [f64; 2] {
    apply(h, p)
}
