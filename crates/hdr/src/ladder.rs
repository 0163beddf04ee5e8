//! Exposure ladders: the thesis's 18-step series and geometric series in general.

use crate::error::{HdrError, HdrResult};

/// Shortest exposure of the thesis's series, seconds.
pub const SEED_SHORTEST_S: f64 = 40e-6;
/// Longest exposure of the thesis's series, seconds.
pub const SEED_LONGEST_S: f64 = 20.0;
/// Number of exposures of the thesis's series.
pub const SEED_EXPOSURE_COUNT: usize = 18;
/// Exposure of the dark frame (thesis §3.3), seconds.
pub const SEED_DARK_EXPOSURE_S: f64 = 60.0;

/// `count` exposure times from `shortest` to `longest` (both included) in geometric progression,
/// ascending.
pub fn geometric_ladder(shortest: f64, longest: f64, count: usize) -> HdrResult<Vec<f64>> {
    if !(shortest.is_finite() && longest.is_finite() && shortest > 0.0 && longest >= shortest) {
        return Err(HdrError::InvalidOption(format!(
            "ladder from {shortest} s to {longest} s"
        )));
    }
    match count {
        0 => Err(HdrError::InvalidOption("empty ladder".into())),
        1 => Ok(vec![shortest]),
        _ => {
            let ratio = (longest / shortest).powf(1.0 / (count - 1) as f64);
            let mut v: Vec<f64> = (0..count)
                .map(|k| shortest * ratio.powi(k as i32))
                .collect();
            // Pin the ends exactly (powi accumulates rounding).
            v[count - 1] = longest;
            Ok(v)
        }
    }
}

/// The thesis's 18 exposures, 40 µs to 20 s, geometric (ratio ≈ 2.164), ascending.
///
/// The thesis (§3.3) takes "a total of 18 10-bit photographs with increasing exposure times ...
/// from 40 microseconds to 20 seconds" without listing the steps. A CCD's response is linear,
/// so what matters is how the steps tile the logarithm of the signal rate; the natural reading is
/// a geometric series, 40 µs · ρ^k for k = 0..17 with ρ = (20 s / 40 µs)^(1/17) ≈ 2.164. With the
/// valid window 10..1000 DN (a factor of ~100 in signal) every rate inside the series' span then
/// falls into the window at ⌊ln 100 / ln ρ⌋ = 5 to 6 exposures.
///
/// # Examples
///
/// ```
/// let ladder = hdr::thesis_ladder();
/// assert_eq!(ladder.len(), 18);
/// assert_eq!((ladder[0], ladder[17]), (40e-6, 20.0));
/// let ratio = ladder[1] / ladder[0];
/// assert!((ratio - 2.164).abs() < 1e-3);
/// // a rate of 1000 DN/s stays inside the 10..1000 DN window at 5 or 6 of the exposures
/// let usable = ladder.iter().filter(|&&t| (10.0..=1000.0).contains(&(1000.0 * t))).count();
/// assert!((5..=6).contains(&usable));
/// ```
pub fn thesis_ladder() -> Vec<f64> {
    geometric_ladder(SEED_SHORTEST_S, SEED_LONGEST_S, SEED_EXPOSURE_COUNT)
        .expect("constant ladder parameters are valid")
}

/// Time the camera is busy with an exposure series: Σ (exposure + readout).
pub fn series_time_s(exposures_s: &[f64], readout_s: f64) -> f64 {
    exposures_s.iter().map(|t| t + readout_s).sum()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn seed_ladder_spans_40us_to_20s_geometrically() {
        let l = thesis_ladder();
        assert_eq!(l.len(), 18);
        assert!((l[0] - 40e-6).abs() < 1e-18);
        assert_eq!(l[17], 20.0);
        let r0 = l[1] / l[0];
        for w in l.windows(2) {
            assert!(((w[1] / w[0]) / r0 - 1.0).abs() < 1e-9);
        }
        assert!((r0 - 2.164).abs() < 1e-3, "ratio {r0}");
    }

    #[test]
    fn invalid_ladders_are_errors() {
        assert!(geometric_ladder(0.0, 1.0, 3).is_err());
        assert!(geometric_ladder(1.0, 0.5, 3).is_err());
        assert!(geometric_ladder(1.0, f64::NAN, 3).is_err());
        assert!(geometric_ladder(1.0, 2.0, 0).is_err());
        assert_eq!(geometric_ladder(1.0, 2.0, 1).unwrap(), vec![1.0]);
    }
}
