//! Sample sphere: centre from digitized surface points and the caliper diameter (thesis §3.2).

use crate::error::{check_finite, CalibError, CalibResult};
use crate::geom::{check_not_collinear, point_spread};
use crate::lm::minimise;
use gantry_hal::{Point3, SphereGeometry};
use nalgebra::{DMatrix, DVector, Vector3};

/// Fitted sphere and its residual.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SphereFit {
    /// Centre and radius (half the caliper diameter).
    pub geometry: SphereGeometry,
    /// RMS of (distance to centre − radius) over the readings, metres.
    pub rms_m: f64,
}

/// Finds the sphere centre from ≥ 4 non-coplanar surface readings and the caliper diameter:
/// algebraic (linear) sphere fit for the start, then Levenberg–Marquardt on the centre with the
/// radius held at half the diameter.
pub fn fit_sphere(points: &[Point3], diameter_m: f64) -> CalibResult<SphereFit> {
    check_finite("caliper diameter", &[diameter_m])?;
    if !(diameter_m > 0.0) {
        return Err(CalibError::Invalid(format!(
            "caliper diameter {diameter_m} m"
        )));
    }
    if points.len() < 4 {
        return Err(CalibError::TooFewPoints {
            what: "sphere surface readings",
            got: points.len(),
            need: 4,
        });
    }
    for p in points {
        check_finite("sphere surface readings", p)?;
    }
    let pts: Vec<Vector3<f64>> = points.iter().map(|p| Vector3::from(*p)).collect();
    let spread = point_spread(&pts);
    check_not_collinear("sphere surface readings", &spread)?;
    if spread.singular[2] < 1e-6 * spread.singular[0] {
        return Err(CalibError::Degenerate(
            "sphere surface readings are coplanar: the centre is ambiguous".into(),
        ));
    }
    let radius = 0.5 * diameter_m;
    // Linear start: |p|² = 2 c·p + d, in coordinates relative to the centroid.
    let c0 = spread.centroid;
    let mut a = DMatrix::zeros(pts.len(), 4);
    let mut b = DVector::zeros(pts.len());
    for (k, p) in pts.iter().enumerate() {
        let q = p - c0;
        a[(k, 0)] = 2.0 * q.x;
        a[(k, 1)] = 2.0 * q.y;
        a[(k, 2)] = 2.0 * q.z;
        a[(k, 3)] = 1.0;
        b[k] = q.norm_squared();
    }
    let start = a
        .clone()
        .svd(true, true)
        .solve(&b, 1e-12)
        .map(|s| c0 + Vector3::new(s[0], s[1], s[2]))
        .unwrap_or(c0);
    let start = if start.iter().all(|v| v.is_finite()) {
        start
    } else {
        c0
    };
    let fit = minimise(
        "sphere centre",
        DVector::from_column_slice(start.as_slice()),
        &[radius * 1e-6; 3],
        |x| {
            let c = Vector3::new(x[0], x[1], x[2]);
            Some(DVector::from_iterator(
                pts.len(),
                pts.iter().map(|p| (p - c).norm() - radius),
            ))
        },
    )?;
    let c = &fit.params;
    Ok(SphereFit {
        geometry: SphereGeometry {
            centre: [c[0], c[1], c[2]],
            radius,
        },
        rms_m: fit.rms(),
    })
}
