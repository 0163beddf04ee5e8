//! Errors of one table against another, defined once for every grid.
//!
//! A [`TableView`] is any table of isotropic BRDF values at points `(θh, θd, φd)`: the MERL
//! table ([`MerlTable`]) and the sample grids of the `sampling` crate implement it, so the same
//! metric serves sparse reconstruction, recovery from photographs and compression.
//!
//! * [`cosine_weighted_relative_rms`]: the relative RMS of `f cos θi` over the bins within
//!   [`GRAZING_LIMIT_DEG`] of the normal on both sides (Ngan et al.'s error, grazing angles left out).
//! * [`table_error`]: the median and 90th percentile of |ln(estimate / truth)| over the bins
//!   where both are positive (a capture against the truth, the real-time view's grid).
//! * [`log_relative_rms`]: `‖ŷ − y‖ / ‖y − ln ε‖` with `y = ln(max(f, 0) + ε)` ([`to_log`],
//!   ε = [`LOG_FLOOR`]) over the valid points of the reference (value finite and ≥ 0, both
//!   directions above the horizon). The denominator is the log-space size of the reference
//!   (`ln(1 + f/ε)`), so an all-black estimate has error 1.
//!
//! ```
//! use brdf::analytic::Lambert;
//! use brdf::metrics::log_relative_rms;
//! use brdf::MerlTable;
//!
//! let a = MerlTable::tabulate(&Lambert { kd: [0.2; 3] });
//! let black = MerlTable::from_values(vec![0.0; brdf::MATERIAL_DIM]).unwrap();
//! assert_eq!(log_relative_rms(&a, &a).unwrap(), 0.0);
//! assert!((log_relative_rms(&a, &black).unwrap() - 1.0).abs() < 1e-12);
//! ```

use crate::corpus::{to_log, LOG_FLOOR};
use crate::error::{BrdfError, Result};
use crate::table::{bin_angles, bin_coords, BINS};
use crate::{HalfDiff, MerlTable};
use rayon::prelude::*;
use std::sync::OnceLock;

/// A table of RGB BRDF values (1/sr; negative = missing) at isotropic points.
pub trait TableView: Sync {
    /// Number of points.
    fn points(&self) -> usize;
    /// Value of `channel` (0..3) at `point`.
    fn value(&self, channel: usize, point: usize) -> f64;
    /// `(θh, θd, φd)` of `point`, radians.
    fn angles(&self, point: usize) -> (f64, f64, f64);
    /// Whether two tables share their points (the same grid).
    fn same_points(&self, other: &Self) -> bool;
}

impl TableView for MerlTable {
    fn points(&self) -> usize {
        BINS
    }
    fn value(&self, channel: usize, point: usize) -> f64 {
        self.get(channel, point)
    }
    fn angles(&self, point: usize) -> (f64, f64, f64) {
        let (i, j, k) = bin_coords(point);
        bin_angles(i, j, k)
    }
    fn same_points(&self, _other: &Self) -> bool {
        true
    }
}

/// Relative RMS error in log space of `estimate` against `reference` (see the [module
/// docs](self)). Tables on different grids, a non-finite estimate at a valid point, or a
/// reference without a valid non-zero point are [`BrdfError::Metric`] errors.
pub fn log_relative_rms<T: TableView>(reference: &T, estimate: &T) -> Result<f64> {
    log_relative_rms_where(reference, estimate, |_| true)
}

/// [`log_relative_rms`] over the points `p` with `keep(p)` only (a region of the table: the
/// bins some photographs constrain, say, or the rest).
pub fn log_relative_rms_where<T: TableView>(
    reference: &T,
    estimate: &T,
    keep: impl Fn(usize) -> bool + Sync,
) -> Result<f64> {
    if !reference.same_points(estimate) || reference.points() != estimate.points() {
        return Err(BrdfError::Metric("tables on different grids".into()));
    }
    let floor = LOG_FLOOR.ln();
    let (num, den, bad) = (0..reference.points())
        .into_par_iter()
        .map(|p| {
            let mut acc = (0.0, 0.0, false);
            if !keep(p) {
                return acc;
            }
            let (th, td, pd) = reference.angles(p);
            if !HalfDiff::isotropic(th, td, pd).above_horizon() {
                return acc;
            }
            for c in 0..3 {
                let v = reference.value(c, p);
                if !(v.is_finite() && v >= 0.0) {
                    continue;
                }
                let e = estimate.value(c, p);
                if !e.is_finite() {
                    acc.2 = true;
                    continue;
                }
                let y = to_log(v);
                acc.0 += (to_log(e) - y).powi(2);
                acc.1 += (y - floor).powi(2);
            }
            acc
        })
        .reduce(
            || (0.0, 0.0, false),
            |a, b| (a.0 + b.0, a.1 + b.1, a.2 || b.2),
        );
    if bad {
        return Err(BrdfError::Metric("non-finite estimate value".into()));
    }
    if den <= 0.0 {
        return Err(BrdfError::Metric(
            "the reference has no valid non-zero points".into(),
        ));
    }
    Ok((num / den).sqrt())
}

/// Grazing limit of the cosine-weighted error (degrees).
pub const GRAZING_LIMIT_DEG: f64 = 80.0;

/// Per bin: `cos θi` if both directions are within [`GRAZING_LIMIT_DEG`], else 0: the weights of
/// [`cosine_weighted_relative_rms`] (computed once).
pub fn cosine_bin_weights() -> &'static [f32] {
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
/// workspace's log error.
///
/// # Examples
///
/// ```
/// use brdf::metrics::cosine_weighted_relative_rms;
/// let lambert = |rho: f64| brdf::MerlTable::tabulate(&brdf::analytic::Lambert { kd: [rho; 3] });
/// let truth = lambert(0.5);
/// assert_eq!(cosine_weighted_relative_rms(&truth, &truth), 0.0);
/// // a table 10 % too bright everywhere is 10 % off
/// assert!((cosine_weighted_relative_rms(&truth, &lambert(0.55)) - 0.1).abs() < 1e-6);
/// ```
pub fn cosine_weighted_relative_rms(truth: &MerlTable, estimate: &MerlTable) -> f64 {
    cosine_weighted_relative_rms_where(truth, estimate, |_| true)
}

/// [`cosine_weighted_relative_rms`] over the bins `b` with `keep(b)` only (a region of the
/// table: the bins some photographs constrain, say, or the rest). Like the whole-table error
/// it is 0 where the region holds no weighted true value and the estimate none either.
pub fn cosine_weighted_relative_rms_where(
    truth: &MerlTable,
    estimate: &MerlTable,
    keep: impl Fn(usize) -> bool + Sync,
) -> f64 {
    let w = cosine_bin_weights();
    let (num, den) = (0..BINS)
        .into_par_iter()
        .map(|b| {
            let cw = w[b] as f64;
            let (mut n, mut d) = (0.0, 0.0);
            if cw > 0.0 && keep(b) {
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

#[cfg(test)]
mod tests {
    use super::*;
    use crate::analytic::{Ggx, Lambert};

    /// Raw values on the MERL grid (NaN allowed), for the error cases.
    struct Raw(Vec<f64>);

    impl TableView for Raw {
        fn points(&self) -> usize {
            BINS
        }
        fn value(&self, channel: usize, point: usize) -> f64 {
            self.0[channel * BINS + point]
        }
        fn angles(&self, point: usize) -> (f64, f64, f64) {
            let (i, j, k) = bin_coords(point);
            bin_angles(i, j, k)
        }
        fn same_points(&self, _other: &Self) -> bool {
            true
        }
    }

    /// The metric against a direct evaluation of its definition on the MERL grid.
    #[test]
    fn agrees_with_its_definition_and_rejects_bad_estimates() {
        let ggx = Ggx {
            kd: [0.1, 0.2, 0.3],
            ks: [0.05; 3],
            alpha: 0.3,
            ior: 1.5,
        };
        let a = MerlTable::tabulate(&ggx);
        let b = MerlTable::tabulate(&Lambert {
            kd: [0.15, 0.1, 0.2],
        });
        let (mut n, mut d) = (0.0, 0.0);
        for bin in 0..BINS {
            let (i, j, k) = bin_coords(bin);
            let (th, td, pd) = bin_angles(i, j, k);
            let (wi, wo) = HalfDiff::isotropic(th, td, pd).to_directions();
            if wi.z < -1e-12 || wo.z < -1e-12 {
                continue;
            }
            for c in 0..3 {
                let (x, y) = (a.get(c, bin), b.get(c, bin));
                if x < 0.0 {
                    continue;
                }
                n += ((y.max(0.0) + 1e-3).ln() - (x + 1e-3).ln()).powi(2);
                d += ((x + 1e-3).ln() - 1e-3f64.ln()).powi(2);
            }
        }
        let want = (n / d).sqrt();
        let got = log_relative_rms(&a, &b).unwrap();
        assert!((got - want).abs() <= 1e-9 * want, "{got} vs {want}");
        assert!(got > 0.1);
        let reference = Raw(a.values());
        let mut nan = b.values();
        nan[BINS + 1000] = f64::NAN;
        assert!(log_relative_rms(&reference, &Raw(nan)).is_err());
        assert!(log_relative_rms(&Raw(vec![0.0; 3 * BINS]), &reference).is_err());
    }

    #[test]
    fn region_errors_see_only_their_region() {
        let truth = MerlTable::tabulate(&Ggx {
            kd: [0.2, 0.3, 0.1],
            ks: [0.5; 3],
            alpha: 0.2,
            ior: 1.5,
        });
        // 10 % too bright on the bins with an even θd index, right elsewhere.
        let region = |b: usize| bin_coords(b).1.is_multiple_of(2);
        let mut v = truth.values();
        for c in 0..3 {
            for b in (0..BINS).filter(|&b| region(b)) {
                v[c * BINS + b] *= 1.1;
            }
        }
        let est = MerlTable::from_values(v).unwrap();
        let inside = cosine_weighted_relative_rms_where(&truth, &est, region);
        let outside = cosine_weighted_relative_rms_where(&truth, &est, |b| !region(b));
        let whole = cosine_weighted_relative_rms(&truth, &est);
        assert!((inside - 0.1).abs() < 1e-9, "{inside}");
        assert_eq!(outside, 0.0);
        assert!(whole > 0.03 && whole < 0.1, "{whole}");
        let log_in = log_relative_rms_where(&truth, &est, region).unwrap();
        let log_out = log_relative_rms_where(&truth, &est, |b| !region(b)).unwrap();
        assert!(log_in > 0.0 && log_out == 0.0, "{log_in} {log_out}");
        // The whole table's error lies between its regions' errors.
        let log_all = log_relative_rms(&truth, &est).unwrap();
        assert!(log_all < log_in && log_all > 0.0);
    }
}

/// Error of a measured table against a known one over the bins where both hold values.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct TableError {
    /// Bins (× channels) compared.
    pub bins: usize,
    /// Median |ln(measured / true)|.
    pub median_abs_log: f64,
    /// 90th percentile of |ln(measured / true)|.
    pub p90_abs_log: f64,
}

/// Error of `measured` against `truth` over bins and channels where both have positive values.
///
/// ```
/// use brdf::MerlTable;
/// let truth = MerlTable::tabulate(&brdf::analytic::Lambert { kd: [0.5; 3] });
/// let mut measured = truth.clone();
/// for v in measured.raw_mut() { *v *= 1.1; }
/// let e = brdf::metrics::table_error(&measured, &truth);
/// assert!((e.median_abs_log - 1.1f64.ln()).abs() < 1e-9);
/// ```
pub fn table_error(measured: &MerlTable, truth: &MerlTable) -> TableError {
    let mut errs = Vec::new();
    for c in 0..3 {
        for b in 0..BINS {
            let (m, t) = (measured.get(c, b), truth.get(c, b));
            if m > 0.0 && t > 0.0 {
                errs.push((m / t).ln().abs());
            }
        }
    }
    errs.sort_by(|a, b| a.total_cmp(b));
    let q = |f: f64| {
        errs.get(((errs.len() as f64 * f) as usize).min(errs.len().saturating_sub(1)))
            .copied()
            .unwrap_or(f64::NAN)
    };
    TableError {
        bins: errs.len(),
        median_abs_log: q(0.5),
        p90_abs_log: q(0.9),
    }
}
