//! The corpus and log transform of `brdf`, with `f32` conveniences (thesis §4.1).

pub use brdf::{log_vector, Corpus, Source, LOG_FLOOR, MATERIAL_DIM};

/// Log-space value of a BRDF value, as `f32` ([`brdf::to_log`]; negative = missing is
/// treated as 0).
#[inline]
pub fn to_log(value: f64) -> f32 {
    brdf::to_log(value) as f32
}

/// BRDF value of an `f32` log-space value ([`brdf::from_log`]); negative when
/// `y < ln(LOG_FLOOR)` (a linear model can produce those: they are physically invalid).
#[inline]
pub fn from_log(y: f32) -> f64 {
    brdf::from_log(y as f64)
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
