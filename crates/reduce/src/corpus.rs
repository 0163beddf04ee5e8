//! A corpus of measured materials as log-space vectors (thesis §4.1).
//!
//! The corpus and the log transform are defined once, in [`brdf::corpus`]; this module
//! re-exports them with the `f32` conveniences the analyses of this crate use. Every material
//! is one vector of `D = 3 × 1,458,000` values: the full MERL table, channel major (R bins,
//! then G, then B), all bins kept, each BRDF value `f` (1/sr) stored as
//! `ln(max(f, 0) + LOG_FLOOR)` (see [`brdf::corpus`] for why the floor is added).

pub use brdf::corpus::{log_vector, values_from_log, Corpus, Source, LOG_FLOOR, MATERIAL_DIM};

/// Log-space value of a BRDF value, as `f32` ([`brdf::corpus::to_log`]; negative = missing is
/// treated as 0).
#[inline]
pub fn to_log(value: f64) -> f32 {
    brdf::corpus::to_log(value) as f32
}

/// BRDF value of an `f32` log-space value ([`brdf::corpus::from_log`]); negative when
/// `y < ln(LOG_FLOOR)` (a linear model can produce those: they are physically invalid).
#[inline]
pub fn from_log(y: f32) -> f64 {
    brdf::corpus::from_log(y as f64)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn log_transform_round_trips_valid_values_and_floors_missing_ones() {
        for v in [0.0, 1e-4, 0.3, 17.0, 3000.0] {
            let back = from_log(to_log(v));
            assert!((back - v).abs() <= 1e-6 * (v + LOG_FLOOR), "{v} -> {back}");
        }
        assert_eq!(to_log(-1.0), to_log(0.0));
        assert!(
            from_log(to_log(0.0) - 0.5) < 0.0,
            "below the floor maps to negative BRDF"
        );
        assert!(log_vector(&[1.0, f64::NAN]).is_err());
    }
}
