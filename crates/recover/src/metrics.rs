//! Errors of a recovered table against the true one, and its validity.

use std::sync::OnceLock;

use brdf::{bin_angles, bin_coords, BINS};
use brdf::{Brdf, HalfDiff, MerlTable};
use rayon::prelude::*;

/// Grazing limit of the cosine-weighted error (degrees).
pub const GRAZING_LIMIT_DEG: f64 = 80.0;

/// Per bin: `cos θi` if both directions are within the grazing limit, else 0.
fn bin_weights() -> &'static [f32] {
    static W: OnceLock<Vec<f32>> = OnceLock::new();
    W.get_or_init(|| {
        let lim = GRAZING_LIMIT_DEG.to_radians().cos();
        (0..BINS)
            .into_par_iter()
            .map(|b| {
                let (i, j, k) = bin_coords(b);
                let (th, td, pd) = bin_angles(i, j, k);
                let hd = HalfDiff::isotropic(th, td, pd);
                let (wi, wo) = hd.to_directions();
                let w = if wi.z >= lim && wo.z >= lim {
                    wi.z
                } else {
                    0.0
                };
                w as f32
            })
            .collect()
    })
}

/// Cosine-weighted relative RMS error of `estimate` against `truth`.
///
/// The error is `√(Σ ((f̂ − f) cos θi)² / Σ (f cos θi)²)` over the bins of the MERL grid with
/// both θi and θo at most 80° (Ngan et al.'s cosine-weighted L2 of ρ · cos θi, grazing angles
/// left out), all three channels, missing true values skipped. [`log_relative_rms`] is the
/// workspace's log error, [`brdf::metrics::log_relative_rms`].
///
/// # Examples
///
/// ```
/// use recover::cosine_weighted_relative_rms;
/// let lambert = |rho: f64| brdf::MerlTable::tabulate(&brdf::analytic::Lambert { kd: [rho; 3] });
/// let truth = lambert(0.5);
/// assert_eq!(cosine_weighted_relative_rms(&truth, &truth), 0.0);
/// // a table 10 % too bright everywhere is 10 % off
/// assert!((cosine_weighted_relative_rms(&truth, &lambert(0.55)) - 0.1).abs() < 1e-6);
/// ```
pub fn cosine_weighted_relative_rms(truth: &MerlTable, estimate: &MerlTable) -> f64 {
    let w = bin_weights();
    let (num, den) = (0..BINS)
        .into_par_iter()
        .map(|b| {
            let cw = w[b] as f64;
            let (mut n, mut d) = (0.0, 0.0);
            if cw > 0.0 {
                for c in 0..3 {
                    let t = truth.get(c, b);
                    if t < 0.0 || !t.is_finite() {
                        continue;
                    }
                    let e = estimate.get(c, b).max(0.0);
                    n += ((e - t) * cw).powi(2);
                    d += (t * cw).powi(2);
                }
            }
            (n, d)
        })
        .reduce(|| (0.0, 0.0), |a, b| (a.0 + b.0, a.1 + b.1));
    (num / den.max(1e-300)).sqrt()
}

/// Relative RMS error in log space of `estimate` against `truth`
/// ([`brdf::metrics::log_relative_rms`]; NaN where the metric is undefined: an all-zero truth or
/// a non-finite estimate).
pub fn log_relative_rms(truth: &MerlTable, estimate: &MerlTable) -> f64 {
    brdf::metrics::log_relative_rms(truth, estimate).unwrap_or(f64::NAN)
}

/// Incidence angles (degrees) at which the directional albedo is checked.
pub const ALBEDO_ANGLES_DEG: [f64; 5] = [0.0, 30.0, 50.0, 70.0, 85.0];

/// Largest directional albedo per channel over [`ALBEDO_ANGLES_DEG`] (`brdf::summary`).
pub fn max_directional_albedo(brdf: &dyn Brdf) -> [f64; 3] {
    let mut m = [0.0f64; 3];
    for a in ALBEDO_ANGLES_DEG {
        let r = brdf::directional_albedo(brdf, a.to_radians(), 96, 64);
        for c in 0..3 {
            m[c] = m[c].max(r[c]);
        }
    }
    m
}
