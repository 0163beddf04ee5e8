//! How a material's coefficients are found from its table.
//!
//! The thesis projects a material orthogonally onto the components: the least-squares fit in
//! the model's space. A least-absolute-deviations fit (iteratively reweighted least squares on
//! a fixed, seeded sample of the entries) gives up the few entries the components cannot
//! follow — a specular peak between two of the corpus's, the grazing rows — instead of
//! spreading their error over every entry, so most entries come closer.

use nalgebra::{DMatrix, DVector};
use rand::seq::index::sample;
use rand::SeedableRng;

use crate::error::{ReduceError, Result};

/// Entries a robust fit samples (all of them for shorter vectors).
pub const ROBUST_SAMPLE: usize = 200_000;
/// Seed of the sample.
pub const ROBUST_SEED: u64 = 0x5eed_0fe1;
/// Residuals below this (in the model's units) weigh as much as this one.
const ROBUST_DELTA: f64 = 1e-3;
/// Most reweighting iterations.
const ROBUST_ITERATIONS: usize = 30;

/// How a full table is encoded to coefficients.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Encoder {
    /// Orthogonal projection: least squares over every entry (the thesis's).
    #[default]
    Projection,
    /// Least absolute deviations over a seeded sample of [`ROBUST_SAMPLE`] entries, started
    /// from the projection.
    Robust,
}

impl Encoder {
    /// Parses `projection` or `robust`.
    pub fn parse(s: &str) -> Result<Encoder> {
        match s {
            "projection" => Ok(Encoder::Projection),
            "robust" => Ok(Encoder::Robust),
            _ => Err(ReduceError::InvalidParameter(format!(
                "unknown encoder {s:?} (expected projection or robust)"
            ))),
        }
    }

    /// The name [`Encoder::parse`] reads.
    pub fn name(&self) -> &'static str {
        match self {
            Encoder::Projection => "projection",
            Encoder::Robust => "robust",
        }
    }
}

/// The sorted entries a robust fit of vectors of length `dim` uses.
pub fn robust_sample(dim: usize) -> Vec<usize> {
    if dim <= ROBUST_SAMPLE {
        return (0..dim).collect();
    }
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(ROBUST_SEED);
    let mut s = sample(&mut rng, dim, ROBUST_SAMPLE).into_vec();
    s.sort_unstable();
    s
}

/// Coefficients `a` minimising `Σ_s |t_s − (U a)_s|` (rows of `u` are entries, columns
/// orthonormal directions), by iteratively reweighted least squares from `a0`.
pub fn least_absolute(u: &DMatrix<f64>, t: &DVector<f64>, a0: DVector<f64>) -> DVector<f64> {
    let k = u.ncols();
    if k == 0 {
        return a0;
    }
    let mut a = a0;
    for _ in 0..ROBUST_ITERATIONS {
        let r = t - u * &a;
        let sw: DVector<f64> = r.map(|v| 1.0 / v.abs().max(ROBUST_DELTA).sqrt());
        let mut uw = u.clone();
        for (mut row, w) in uw.row_iter_mut().zip(sw.iter()) {
            row *= *w;
        }
        let tw = t.component_mul(&sw);
        let mut normal = uw.transpose() * &uw;
        let scale = normal.diagonal().max().max(1e-300);
        for c in 0..k {
            normal[(c, c)] += 1e-12 * scale;
        }
        let rhs = uw.transpose() * tw;
        let Some(chol) = normal.cholesky() else {
            break;
        };
        let next = chol.solve(&rhs);
        let change = (&next - &a).norm() / next.norm().max(1e-300);
        a = next;
        if change < 1e-7 {
            break;
        }
    }
    a
}

#[cfg(test)]
mod tests {
    use super::*;

    /// On data that a line fits except for a few gross outliers, the robust fit finds the
    /// line and least squares does not.
    #[test]
    fn least_absolute_ignores_a_few_outliers() {
        let n = 200;
        let u = DMatrix::from_fn(n, 2, |i, c| if c == 0 { 1.0 } else { i as f64 / n as f64 });
        let mut t = DVector::from_fn(n, |i, _| 0.5 + 2.0 * i as f64 / n as f64);
        for i in [3, 50, 120, 121, 190] {
            t[i] += 30.0;
        }
        let ls = u.clone().svd(true, true).solve(&t, 1e-12).unwrap();
        let robust = least_absolute(&u, &t, ls.clone());
        assert!(
            (robust[0] - 0.5).abs() < 1e-4 && (robust[1] - 2.0).abs() < 1e-4,
            "{robust}"
        );
        assert!((ls[0] - 0.5).abs() > 0.3, "{ls}");
        assert_eq!(robust_sample(10), (0..10).collect::<Vec<_>>());
        let s = robust_sample(1_000_000);
        assert_eq!(s.len(), ROBUST_SAMPLE);
        assert!(s.windows(2).all(|w| w[0] < w[1]));
        assert_eq!(s, robust_sample(1_000_000), "seeded");
        for (name, e) in [
            ("projection", Encoder::Projection),
            ("robust", Encoder::Robust),
        ] {
            assert_eq!(Encoder::parse(name).unwrap(), e);
            assert_eq!(e.name(), name);
        }
        assert!(Encoder::parse("l1").is_err());
    }
}
