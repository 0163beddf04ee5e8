//! Lamp circle from digitized lamp positions (thesis §3.2): least-squares plane, projection,
//! circle fit by Levenberg–Marquardt, then the reference direction at turntable angle 0.

use crate::error::{check_finite, CalibError, CalibResult};
use crate::geom::{check_not_collinear, point_spread};
use crate::lm::minimise;
use gantry_hal::{LampCircle, Point3};
use nalgebra::{DVector, Vector3};
use serde::{Deserialize, Serialize};

/// One digitizer reading of the lamp with the turntable at a known angle.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct LampReading {
    /// Turntable angle, degrees.
    pub angle_deg: f64,
    /// Digitized lamp position, world metres.
    pub position: Point3,
}

/// Fitted lamp circle and residuals.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LampFit {
    /// The circle with its reference direction.
    pub circle: LampCircle,
    /// RMS distance of the readings from the circle plane, metres.
    pub plane_rms_m: f64,
    /// RMS in-plane radial residual of the circle fit, metres.
    pub circle_rms_m: f64,
    /// RMS 3-D distance between each reading and the model position at its turntable angle.
    pub rms_m: f64,
}

/// Fits the lamp circle to ≥ 3 readings spread over more than one turntable angle.
///
/// The plane is the total-least-squares plane of the readings; the readings are projected
/// into it and a circle is fitted in 2-D (algebraic start, then Levenberg–Marquardt on the
/// geometric distance). The normal is oriented so that turntable angles grow counter-clockwise
/// about it, and the reference direction is the circular mean of (in-plane angle − turntable
/// angle).
pub fn fit_lamp_circle(readings: &[LampReading]) -> CalibResult<LampFit> {
    if readings.len() < 3 {
        return Err(CalibError::TooFewPoints {
            what: "lamp readings",
            got: readings.len(),
            need: 3,
        });
    }
    for r in readings {
        check_finite("lamp readings", &r.position)?;
        check_finite("lamp readings", &[r.angle_deg])?;
    }
    let pts: Vec<Vector3<f64>> = readings.iter().map(|r| Vector3::from(r.position)).collect();
    let spread = point_spread(&pts);
    check_not_collinear("lamp readings", &spread)?;
    let o = spread.centroid;
    let mut n = spread.axes[2].normalize();
    let e1 = spread.axes[0].normalize();
    let plane_rms_m =
        (pts.iter().map(|p| (p - o).dot(&n).powi(2)).sum::<f64>() / pts.len() as f64).sqrt();
    let project = |n: &Vector3<f64>| -> Vec<[f64; 2]> {
        let e2 = n.cross(&e1);
        pts.iter()
            .map(|p| {
                let d = p - o;
                [d.dot(&e1), d.dot(&e2)]
            })
            .collect()
    };
    let q = project(&n);
    // Algebraic (Kåsa) start: a² + b² = 2 ca a + 2 cb b + d.
    let m = q.len();
    let mut a = nalgebra::DMatrix::zeros(m, 3);
    let mut b = DVector::zeros(m);
    for (k, p) in q.iter().enumerate() {
        a[(k, 0)] = 2.0 * p[0];
        a[(k, 1)] = 2.0 * p[1];
        a[(k, 2)] = 1.0;
        b[k] = p[0] * p[0] + p[1] * p[1];
    }
    let s = a
        .svd(true, true)
        .solve(&b, 1e-14)
        .map_err(|e| CalibError::Degenerate(format!("lamp circle: {e}")))?;
    let r0 = (s[2] + s[0] * s[0] + s[1] * s[1]).max(0.0).sqrt();
    if !(r0 > 0.0) || !s.iter().all(|v| v.is_finite()) {
        return Err(CalibError::Degenerate(
            "lamp circle: no circle through the readings".into(),
        ));
    }
    let scale = r0;
    let fit = minimise(
        "lamp circle",
        DVector::from_vec(vec![s[0], s[1], r0]),
        &[scale * 1e-7; 3],
        |x| {
            Some(DVector::from_iterator(
                m,
                q.iter()
                    .map(|p| ((p[0] - x[0]).powi(2) + (p[1] - x[1]).powi(2)).sqrt() - x[2]),
            ))
        },
    )?;
    let (ca, cb, radius) = (fit.params[0], fit.params[1], fit.params[2].abs());
    let circle_rms_m = fit.rms();
    // Orientation and phase.
    let angles: Vec<f64> = readings.iter().map(|r| r.angle_deg.to_radians()).collect();
    let amin = angles.iter().cloned().fold(f64::INFINITY, f64::min);
    let amax = angles.iter().cloned().fold(f64::NEG_INFINITY, f64::max);
    if amax - amin < 1f64.to_radians() {
        return Err(CalibError::Degenerate(
            "lamp readings span less than 1° of turntable angle: orientation unknown".into(),
        ));
    }
    let phase = |q: &[[f64; 2]], sign: f64| -> (f64, f64) {
        let (mut sx, mut sy) = (0.0, 0.0);
        for (p, &t) in q.iter().zip(&angles) {
            let phi = (p[1] - cb * sign).atan2(p[0] - ca);
            let d = phi - t;
            sx += d.cos();
            sy += d.sin();
        }
        let alpha = sy.atan2(sx);
        let coherence = (sx * sx + sy * sy).sqrt() / q.len() as f64;
        (alpha, coherence)
    };
    let (mut alpha, c_plus) = phase(&q, 1.0);
    let n_flipped = -n;
    let q_flipped = project(&n_flipped);
    let (alpha_f, c_minus) = phase(&q_flipped, -1.0);
    let mut cb_world = cb;
    if c_minus > c_plus {
        n = n_flipped;
        alpha = alpha_f;
        cb_world = -cb;
    }
    let e2 = n.cross(&e1);
    let centre = o + ca * e1 + cb_world * e2;
    let reference = (alpha.cos() * e1 + alpha.sin() * e2).normalize();
    let circle = LampCircle {
        centre: [centre.x, centre.y, centre.z],
        normal: [n.x, n.y, n.z],
        radius,
        reference: [reference.x, reference.y, reference.z],
    };
    let rms_m = (readings
        .iter()
        .zip(&pts)
        .map(|(r, p)| (circle.position(r.angle_deg) - p).norm_squared())
        .sum::<f64>()
        / readings.len() as f64)
        .sqrt();
    Ok(LampFit {
        circle,
        plane_rms_m,
        circle_rms_m,
        rms_m,
    })
}
