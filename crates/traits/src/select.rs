//! The default fit of rated traits: a ridge variant chosen by leave-one-out inside the rated
//! materials, and its honest score by nested leave-one-out.
//!
//! A rated trait is a linear direction in the space (editing moves along it), so the variants
//! are linear: ridge regression on the first `dims` coordinates of the space (the rest of the
//! direction is zero) with penalty `lambda · n` on standardised coordinates. Which variant
//! predicts a trait best differs between traits (a weak trait wants few coordinates and a large
//! penalty) and cannot be read off the scores it is reported with. So:
//!
//! * [`select_ridge`] picks the variant whose leave-one-out scores on the given materials rank
//!   their ratings best (Spearman ρ). The leave-one-out is exact and cheap: every variant is one
//!   small linear system, and each held-out solution is a rank-one downdate of it.
//! * [`nested_loo_scores`] scores that whole procedure: each material is held out in turn, the
//!   variant is selected again on the other materials only, fitted on them and applied to the
//!   held-out one. The Spearman ρ of these scores with the ratings is the figure a material the
//!   procedure never saw can expect; no choice in it ever looked at the score it is judged by.

use nalgebra::{DMatrix, DVector};
use serde::{Deserialize, Serialize};

use crate::direction::{fit_ridge, Direction, FitOptions};
use crate::error::{Result, TraitsError};
use crate::study::spearman;

/// Numbers of leading coordinates a rated trait may use (those below the space's dimension,
/// and the whole space).
pub const VARIANT_DIMS: [usize; 8] = [2, 3, 5, 7, 10, 15, 20, 30];

/// Ridge penalties per rated material (`λ = lambda · n` on coordinates standardised to unit
/// RMS radius).
pub const VARIANT_LAMBDAS: [f64; 5] = [1e-3, 1e-2, 0.1, 1.0, 10.0];

/// One ridge-regression variant for a rated trait.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct RidgeVariant {
    /// Leading coordinates of the space used (the direction is zero beyond them).
    pub dims: usize,
    /// Penalty per rated material.
    pub lambda: f64,
}

impl RidgeVariant {
    /// The default candidates in a space of dimension `dim`: every entry of [`VARIANT_DIMS`]
    /// below `dim` and `dim` itself, each with every penalty of [`VARIANT_LAMBDAS`].
    pub fn grid(dim: usize) -> Vec<RidgeVariant> {
        let mut dims: Vec<usize> = VARIANT_DIMS.iter().copied().filter(|&d| d < dim).collect();
        if dim > 0 {
            dims.push(dim);
        }
        dims.iter()
            .flat_map(|&dims| {
                VARIANT_LAMBDAS
                    .iter()
                    .map(move |&lambda| RidgeVariant { dims, lambda })
            })
            .collect()
    }

    fn check(&self, x: &DMatrix<f64>) -> Result<()> {
        if self.dims == 0 || self.dims > x.ncols() || !self.lambda.is_finite() || self.lambda <= 0.0
        {
            return Err(TraitsError::InvalidParameter(format!(
                "ridge variant of {} coordinates and λ {} per point in a space of {}",
                self.dims,
                self.lambda,
                x.ncols()
            )));
        }
        Ok(())
    }

    /// Fits the variant: the ridge direction on the leading coordinates, padded with zeros to
    /// the space's dimension.
    pub fn fit(&self, x: &DMatrix<f64>, r: &[f64]) -> Result<Direction> {
        self.check(x)?;
        let lead = x.columns(0, self.dims).into_owned();
        let opts = FitOptions {
            ridge_lambda: Some(self.lambda * x.nrows() as f64),
            ..FitOptions::default()
        };
        let (mut d, _) = fit_ridge(&lead, r, &opts)?;
        d.w.resize(x.ncols(), 0.0);
        Ok(d)
    }

    /// Exact leave-one-out scores `wᵢ·(xᵢ − x̄)` of the variant on the rows of `x`: `wᵢ` fitted
    /// without row `i`, on coordinates centred and scaled once over all rows (the intercept is
    /// not penalised, so the centring does not change the fit; the fold's rating mean is left
    /// out of the score, see [`crate::loo_ridge_scores`]).
    pub fn loo_scores(&self, x: &DMatrix<f64>, r: &[f64]) -> Result<Vec<f64>> {
        self.check(x)?;
        let n = x.nrows();
        check_ratings(x, r)?;
        if n < 4 {
            return Err(TraitsError::InvalidParameter(
                "leave-one-out ridge needs at least 4 ratings".into(),
            ));
        }
        let d = self.dims;
        let lead = x.columns(0, d);
        let mean = lead.row_mean();
        let mut z = DMatrix::from_fn(n, d, |i, k| lead[(i, k)] - mean[k]);
        let rms = (z.norm_squared() / n as f64).sqrt();
        if rms > 0.0 {
            z /= rms;
        }
        // Augmented design [1, z], penalty diag(0, λ, …, λ).
        let a = DMatrix::from_fn(n, d + 1, |i, k| if k == 0 { 1.0 } else { z[(i, k - 1)] });
        let mut g = a.transpose() * &a;
        let lam = self.lambda * n as f64;
        for k in 1..=d {
            g[(k, k)] += lam;
        }
        let m = g
            .cholesky()
            .ok_or_else(|| TraitsError::Numerical("ridge system not positive".into()))?
            .inverse();
        let y = DVector::from_column_slice(r);
        let beta = &m * (a.transpose() * &y);
        (0..n)
            .map(|i| {
                let ai = a.row(i).transpose();
                let mai = &m * &ai;
                let h = ai.dot(&mai);
                let e = y[i] - ai.dot(&beta);
                if 1.0 - h <= 1e-12 {
                    return Err(TraitsError::Numerical(format!(
                        "material {i} has leverage 1 in ridge leave-one-out"
                    )));
                }
                // β without row i: β − M aᵢ eᵢ / (1 − hᵢ).
                let bi = &beta - mai * (e / (1.0 - h));
                Ok((1..=d).map(|k| bi[k] * z[(i, k - 1)]).sum())
            })
            .collect()
    }
}

fn check_ratings(x: &DMatrix<f64>, r: &[f64]) -> Result<()> {
    if r.len() != x.nrows() {
        return Err(TraitsError::Dimension {
            what: "ratings per point",
            expected: x.nrows(),
            got: r.len(),
        });
    }
    Ok(())
}

/// The variant of `variants` whose leave-one-out scores on `(x, r)` rank the ratings best, and
/// that ρ. Ties go to the earlier variant.
pub fn select_ridge(
    x: &DMatrix<f64>,
    r: &[f64],
    variants: &[RidgeVariant],
) -> Result<(RidgeVariant, f64)> {
    let mut best: Option<(RidgeVariant, f64)> = None;
    for v in variants {
        let rho = spearman(&v.loo_scores(x, r)?, r);
        if best.is_none_or(|(_, b)| rho > b) {
            best = Some((*v, rho));
        }
    }
    best.ok_or_else(|| TraitsError::InvalidParameter("no ridge variant to choose from".into()))
}

/// Nested leave-one-out: for each row in turn, the variant selected by [`select_ridge`] on the
/// other rows, fitted on them, scores the held-out row (`w·x`, without the fold's intercept).
/// Returns the scores and each fold's choice.
pub fn nested_loo_scores(
    x: &DMatrix<f64>,
    r: &[f64],
    variants: &[RidgeVariant],
) -> Result<(Vec<f64>, Vec<RidgeVariant>)> {
    let n = x.nrows();
    check_ratings(x, r)?;
    let mut scores = Vec::with_capacity(n);
    let mut chosen = Vec::with_capacity(n);
    for i in 0..n {
        let xi = x.clone().remove_row(i);
        let mut ri = r.to_vec();
        ri.remove(i);
        let (v, _) = select_ridge(&xi, &ri, variants)?;
        let d = v.fit(&xi, &ri)?;
        let held = x.row(i).transpose();
        scores.push(d.score(held.as_slice()) - d.b);
        chosen.push(v);
    }
    Ok((scores, chosen))
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{Rng, SeedableRng};

    fn variant(dims: usize, lambda: f64) -> RidgeVariant {
        RidgeVariant { dims, lambda }
    }

    fn data(n: usize, d: usize, seed: u64) -> (DMatrix<f64>, Vec<f64>) {
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed);
        let x = DMatrix::from_fn(n, d, |_, k| rng.gen_range(-1.0..1.0) * (d - k) as f64);
        // The rating reads the first two coordinates, plus noise.
        let r = (0..n)
            .map(|i| 0.5 + 0.1 * x[(i, 0)] - 0.2 * x[(i, 1)] + rng.gen_range(-0.05..0.05))
            .collect();
        (x, r)
    }

    #[test]
    fn closed_form_leave_one_out_matches_refitting() {
        let (x, r) = data(30, 6, 5);
        for v in [variant(3, 0.1), variant(6, 1e-3)] {
            let fast = v.loo_scores(&x, &r).unwrap();
            // Refitting without each row, on the same centring and scale as the closed form.
            let lead = x.columns(0, v.dims).into_owned();
            let mean = lead.row_mean();
            let c = DMatrix::from_fn(30, v.dims, |i, k| lead[(i, k)] - mean[k]);
            let rms = (c.norm_squared() / 30.0).sqrt();
            for i in 0..30 {
                let zi = (&c / rms).remove_row(i);
                let mut ri = r.clone();
                ri.remove(i);
                let a = DMatrix::from_fn(
                    29,
                    v.dims + 1,
                    |j, k| {
                        if k == 0 {
                            1.0
                        } else {
                            zi[(j, k - 1)]
                        }
                    },
                );
                let mut g = a.transpose() * &a;
                for k in 1..=v.dims {
                    g[(k, k)] += v.lambda * 30.0;
                }
                let beta = g
                    .lu()
                    .solve(&(a.transpose() * DVector::from_vec(ri)))
                    .unwrap();
                let s: f64 = (1..=v.dims).map(|k| beta[k] * c[(i, k - 1)] / rms).sum();
                assert!(
                    (s - fast[i]).abs() < 1e-10,
                    "{v:?} row {i}: {s} {}",
                    fast[i]
                );
            }
        }
    }

    #[test]
    fn selection_prefers_the_coordinates_that_carry_the_rating() {
        let (x, r) = data(60, 10, 7);
        let (v, rho) = select_ridge(&x, &r, &RidgeVariant::grid(10)).unwrap();
        // One coordinate cannot carry a rating that reads two; every grid entry uses two or more.
        assert!(v.dims >= 2, "{v:?}");
        assert!(rho > 0.9, "{rho}");
        let (scores, chosen) = nested_loo_scores(&x, &r, &RidgeVariant::grid(10)).unwrap();
        assert_eq!(chosen.len(), 60);
        assert!(spearman(&scores, &r) > 0.9);
    }

    #[test]
    fn pure_noise_is_not_predicted_by_the_nested_scores() {
        // Ratings independent of the coordinates: selecting the best of 40 variants makes the
        // inner ρ look good, but the nested leave-one-out ρ stays near zero.
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(11);
        let (x, _) = data(50, 10, 9);
        let r: Vec<f64> = (0..50).map(|_| rng.gen_range(0.0..1.0)).collect();
        let grid = RidgeVariant::grid(10);
        let (_, inner) = select_ridge(&x, &r, &grid).unwrap();
        let (scores, _) = nested_loo_scores(&x, &r, &grid).unwrap();
        let outer = spearman(&scores, &r);
        assert!(outer < inner, "outer {outer} inner {inner}");
        assert!(outer.abs() < 0.35, "{outer}");
    }

    #[test]
    fn bad_variants_are_refused() {
        let (x, r) = data(10, 3, 1);
        for v in [variant(0, 1.0), variant(4, 1.0), variant(2, f64::NAN)] {
            assert!(v.loo_scores(&x, &r).is_err());
            assert!(v.fit(&x, &r).is_err());
        }
        assert!(select_ridge(&x, &r, &[]).is_err());
        assert_eq!(RidgeVariant::grid(3).len(), 2 * VARIANT_LAMBDAS.len());
        assert_eq!(RidgeVariant::grid(45).len(), 9 * VARIANT_LAMBDAS.len());
    }
}
