//! Errors of a recovered table against the true one, and its validity.

use brdf::{Brdf, MerlTable};

pub use brdf::metrics::cosine_weighted_relative_rms;

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
