//! Fitting whole trait sets and measuring how well each trait is determined.

use nalgebra::{DMatrix, DVector};

use crate::direction::{fit_binary, fit_ridge, Direction, FitOptions, Method};
use crate::error::{Result, TraitsError};
use crate::labels::{Label, LabelSet, RatingSet};
use crate::navigate::{Space, TraitSet, TraitVector};
use crate::select::{nested_loo_scores, select_ridge, RidgeVariant};

/// Rows of `coords` (named by `names`) with a label for trait `t`, and the labels.
pub fn labelled_rows(
    coords: &DMatrix<f64>,
    names: &[String],
    labels: &LabelSet,
    t: usize,
) -> Result<(DMatrix<f64>, Vec<bool>)> {
    let mut rows = Vec::new();
    let mut y = Vec::new();
    for (m, l) in labels.column(t) {
        if l == Label::Unspecified {
            continue;
        }
        let i = names
            .iter()
            .position(|n| n == m)
            .ok_or_else(|| TraitsError::UnknownMaterial(m.into()))?;
        rows.push(i);
        y.push(l == Label::Present);
    }
    Ok((coords.select_rows(&rows), y))
}

/// Rows of `coords` with a rating for trait `t`, and the ratings.
pub fn rated_rows(
    coords: &DMatrix<f64>,
    names: &[String],
    ratings: &RatingSet,
    t: usize,
) -> Result<(DMatrix<f64>, Vec<f64>)> {
    let mut rows = Vec::new();
    let mut r = Vec::new();
    for (m, v) in ratings.column(t) {
        let Some(v) = v else { continue };
        let i = names
            .iter()
            .position(|n| n == m)
            .ok_or_else(|| TraitsError::UnknownMaterial(m.into()))?;
        rows.push(i);
        r.push(v);
    }
    Ok((coords.select_rows(&rows), r))
}

/// Leave-one-out accuracy of the sign of the score of a binary method.
pub fn loo_sign_accuracy(
    x: &DMatrix<f64>,
    y: &[bool],
    method: Method,
    opts: &FitOptions,
) -> Result<f64> {
    let n = x.nrows();
    let mut right = 0;
    for i in 0..n {
        let xi = x.clone().remove_row(i);
        let mut yi = y.to_vec();
        yi.remove(i);
        let d = fit_binary(&xi, &yi, method, opts)?;
        let s = d.score(x.row(i).transpose().as_slice());
        if (s > d.threshold) == y[i] {
            right += 1;
        }
    }
    Ok(right as f64 / n as f64)
}

/// Leave-one-out predictions of ridge regression (λ chosen again inside every fold): the
/// held-out rating's estimate `w·x + b`.
pub fn loo_ridge_predictions(x: &DMatrix<f64>, r: &[f64], opts: &FitOptions) -> Result<Vec<f64>> {
    loo_ridge(x, r, opts, true)
}

/// Leave-one-out trait scores of ridge regression: `w·x`, the fold's direction applied to
/// the held-out material, without the intercept.
///
/// The intercept `b` carries the mean of the fold's ratings, `(Σr − rᵢ)/(n − 1)`, which
/// falls exactly as the held-out rating `rᵢ` rises. Where a trait's direction carries
/// little signal, that term alone makes leave-one-out predictions anti-correlated with the
/// ratings (a known bias of leave-one-out correlation). A trait is used through its score
/// `w·x` (editing moves along `w`), whose ranking no fold-dependent constant disturbs: these
/// are the figures to rank traits by.
pub fn loo_ridge_scores(x: &DMatrix<f64>, r: &[f64], opts: &FitOptions) -> Result<Vec<f64>> {
    loo_ridge(x, r, opts, false)
}

fn loo_ridge(
    x: &DMatrix<f64>,
    r: &[f64],
    opts: &FitOptions,
    with_intercept: bool,
) -> Result<Vec<f64>> {
    leave_one_out(x, r, |xi, ri, held| {
        let (d, _) = fit_ridge(xi, ri, opts)?;
        let s = d.score(held);
        Ok(if with_intercept { s } else { s - d.b })
    })
}

/// `predict(training rows, their ratings, held-out row)` for every row held out in turn.
fn leave_one_out(
    x: &DMatrix<f64>,
    r: &[f64],
    predict: impl Fn(&DMatrix<f64>, &[f64], &[f64]) -> Result<f64>,
) -> Result<Vec<f64>> {
    (0..x.nrows())
        .map(|i| {
            let xi = x.clone().remove_row(i);
            let mut ri = r.to_vec();
            ri.remove(i);
            predict(&xi, &ri, x.row(i).transpose().as_slice())
        })
        .collect()
}

/// The hyper-parameter grid of kernel ridge regression with a Gaussian (RBF) kernel
/// `k(x, x') = exp(−‖x − x'‖² / (s · m))`, `m` the median squared distance between training
/// points, `s` a width from [`KernelRidgeGrid::widths`].
#[derive(Debug, Clone, PartialEq)]
pub struct KernelRidgeGrid {
    /// Kernel widths `s` (relative to the median squared distance).
    pub widths: Vec<f64>,
    /// Ridge parameters λ (relative to the number of training points).
    pub lambdas: Vec<f64>,
    /// Choose the grid point by the Spearman ρ of the exact leave-one-out predictions
    /// (the study's own measure) instead of their squared error.
    pub select_by_rank: bool,
}

impl Default for KernelRidgeGrid {
    fn default() -> Self {
        KernelRidgeGrid {
            widths: vec![0.25, 0.5, 1.0, 2.0, 4.0, 8.0],
            lambdas: vec![1e-3, 3e-3, 1e-2, 3e-2, 0.1, 0.3, 1.0],
            select_by_rank: false,
        }
    }
}

/// A kernel ridge fit: `ŷ(x) = ȳ + Σ αᵢ k(x, xᵢ)`.
#[derive(Debug, Clone)]
pub struct KernelRidge {
    points: DMatrix<f64>,
    alpha: Vec<f64>,
    mean: f64,
    scale: f64,
    /// Chosen width `s`.
    pub width: f64,
    /// Chosen λ (relative).
    pub lambda: f64,
}

fn sq_dists(a: &DMatrix<f64>, b: &DMatrix<f64>) -> DMatrix<f64> {
    DMatrix::from_fn(a.nrows(), b.nrows(), |i, j| {
        (a.row(i) - b.row(j)).norm_squared()
    })
}

impl KernelRidge {
    /// Fits on rows `x` and targets `y`, choosing width and λ from `grid` by the exact
    /// leave-one-out squared error (from the eigen-decomposition of the kernel matrix).
    pub fn fit(x: &DMatrix<f64>, y: &[f64], grid: &KernelRidgeGrid) -> Result<KernelRidge> {
        let n = x.nrows();
        if n < 3 || y.len() != n || grid.widths.is_empty() || grid.lambdas.is_empty() {
            return Err(TraitsError::InvalidParameter(
                "kernel ridge needs ≥ 3 rows, one target per row and a grid".into(),
            ));
        }
        let d = sq_dists(x, x);
        let mut off: Vec<f64> = (0..n)
            .flat_map(|i| (0..n).filter(move |&j| j != i).map(move |j| (i, j)))
            .map(|(i, j)| d[(i, j)])
            .collect();
        off.sort_by(|a, b| a.total_cmp(b));
        let med = off[off.len() / 2].max(1e-300);
        let mean = y.iter().sum::<f64>() / n as f64;
        let yc = DVector::from_iterator(n, y.iter().map(|v| v - mean));
        let mut best: Option<(f64, f64, f64)> = None;
        for &s in &grid.widths {
            let k = d.map(|v| (-v / (s * med)).exp());
            let eig = k.clone().symmetric_eigen();
            let q = &eig.eigenvectors;
            let qty = q.transpose() * &yc;
            for &l in &grid.lambdas {
                let lam = l * n as f64;
                // ŷ = Q diag(λk/(λk+λ)) Qᵀ y; H_ii = Σ_k Q_ik² λk/(λk+λ).
                let g: Vec<f64> = eig
                    .eigenvalues
                    .iter()
                    .map(|&e| e.max(0.0) / (e.max(0.0) + lam))
                    .collect();
                let mut err = 0.0;
                let mut loo = Vec::with_capacity(n);
                for i in 0..n {
                    let (mut yh, mut h) = (0.0, 0.0);
                    for kx in 0..n {
                        yh += q[(i, kx)] * g[kx] * qty[kx];
                        h += q[(i, kx)].powi(2) * g[kx];
                    }
                    let e = (yc[i] - yh) / (1.0 - h).max(1e-9);
                    err += e * e;
                    loo.push(yc[i] - e);
                }
                if grid.select_by_rank {
                    err = -spearman(&loo, yc.as_slice());
                }
                if best.is_none_or(|b| err < b.0) {
                    best = Some((err, s, l));
                }
            }
        }
        let (_, width, lambda) = best.ok_or_else(|| TraitsError::Numerical("grid".into()))?;
        let mut a = d.map(|v| (-v / (width * med)).exp());
        for i in 0..n {
            a[(i, i)] += lambda * n as f64;
        }
        let alpha = a
            .cholesky()
            .ok_or_else(|| TraitsError::Numerical("kernel matrix".into()))?
            .solve(&yc);
        Ok(KernelRidge {
            points: x.clone(),
            alpha: alpha.iter().copied().collect(),
            mean,
            scale: width * med,
            width,
            lambda,
        })
    }

    /// Prediction at `x`.
    pub fn predict(&self, x: &[f64]) -> f64 {
        self.mean + self.deviation(x)
    }

    /// Prediction at `x` less the training ratings' mean: the kernel part alone.
    pub fn deviation(&self, x: &[f64]) -> f64 {
        let p = DMatrix::from_row_slice(1, x.len(), x);
        let d = sq_dists(&p, &self.points);
        d.iter()
            .zip(&self.alpha)
            .map(|(v, a)| (-v / self.scale).exp() * a)
            .sum::<f64>()
    }
}

/// Leave-one-out predictions of kernel ridge regression, the width and λ chosen again inside
/// every fold (nested: by exact leave-one-out on the fold's training rows only).
pub fn loo_kernel_ridge_predictions(
    x: &DMatrix<f64>,
    r: &[f64],
    grid: &KernelRidgeGrid,
) -> Result<Vec<f64>> {
    loo_kernel_ridge(x, r, grid, true)
}

fn loo_kernel_ridge(
    x: &DMatrix<f64>,
    r: &[f64],
    grid: &KernelRidgeGrid,
    with_mean: bool,
) -> Result<Vec<f64>> {
    leave_one_out(x, r, |xi, ri, held| {
        let m = KernelRidge::fit(xi, ri, grid)?;
        Ok(if with_mean {
            m.predict(held)
        } else {
            m.deviation(held)
        })
    })
}

/// Leave-one-out kernel ridge scores without the fold's rating mean (see
/// [`loo_ridge_scores`] for why the mean is left out when ranking).
pub fn loo_kernel_ridge_scores(
    x: &DMatrix<f64>,
    r: &[f64],
    grid: &KernelRidgeGrid,
) -> Result<Vec<f64>> {
    loo_kernel_ridge(x, r, grid, false)
}

/// Spearman's rank correlation (average ranks for ties).
pub fn spearman(a: &[f64], b: &[f64]) -> f64 {
    fn ranks(v: &[f64]) -> Vec<f64> {
        let mut idx: Vec<usize> = (0..v.len()).collect();
        idx.sort_by(|&i, &j| v[i].total_cmp(&v[j]));
        let mut r = vec![0.0; v.len()];
        let mut i = 0;
        while i < idx.len() {
            let mut j = i;
            while j + 1 < idx.len() && v[idx[j + 1]] == v[idx[i]] {
                j += 1;
            }
            let avg = (i + j) as f64 / 2.0 + 1.0;
            for k in i..=j {
                r[idx[k]] = avg;
            }
            i = j + 1;
        }
        r
    }
    let (ra, rb) = (ranks(a), ranks(b));
    let n = a.len() as f64;
    let (ma, mb) = (ra.iter().sum::<f64>() / n, rb.iter().sum::<f64>() / n);
    let (mut sab, mut saa, mut sbb) = (0.0, 0.0, 0.0);
    for (x, y) in ra.iter().zip(&rb) {
        sab += (x - ma) * (y - mb);
        saa += (x - ma).powi(2);
        sbb += (y - mb).powi(2);
    }
    if saa == 0.0 || sbb == 0.0 {
        0.0
    } else {
        sab / (saa * sbb).sqrt()
    }
}

/// Fits every trait of a label set (binary methods) or rating set (ridge) on the corpus
/// coordinates of a space; `cross_validate` adds the leave-one-out agreement to each trait:
///
/// * Binary traits: leave-one-out accuracy of the sign of the score (the held-out material's
///   score against the classifier's threshold, the trait refitted without it).
/// * Rated traits: leave-one-out Spearman ρ between each held-out material's predicted score
///   and its human rating.
/// * The angle between the directions of two methods for the same trait.
pub struct SetFit<'a> {
    /// Corpus coordinates in the space (`N × d`).
    pub coords: &'a DMatrix<f64>,
    /// Corpus names (rows of `coords`).
    pub names: &'a [String],
    /// The space.
    pub space: Space,
    /// Method tunables.
    pub options: FitOptions,
    /// Whether to measure leave-one-out agreement.
    pub cross_validate: bool,
}

impl SetFit<'_> {
    /// Binary traits of a label set with `method` (mean, Fisher or SVM).
    pub fn binary(&self, labels: &LabelSet, method: Method) -> Result<TraitSet> {
        labels.check(self.names)?;
        self.trait_set(&labels.traits, method, |t| {
            let (x, y) = labelled_rows(self.coords, self.names, labels, t)?;
            let direction = fit_binary(&x, &y, method, &self.options)?;
            let cv = if self.cross_validate {
                Some(loo_sign_accuracy(&x, &y, method, &self.options)?)
            } else {
                None
            };
            Ok((direction, cv, None))
        })
    }

    /// Graded traits of a rating set by ridge regression.
    ///
    /// With no fixed penalty in the options (the default), each trait's variant (leading
    /// coordinates and penalty) is chosen by [`select_ridge`] over [`RidgeVariant::grid`], and
    /// its leave-one-out agreement is the nested one of [`nested_loo_scores`]: the choice made
    /// again without each held-out material. With a fixed `ridge_lambda`, every trait uses the
    /// whole space and that penalty, scored by plain leave-one-out.
    pub fn ratings(&self, ratings: &RatingSet) -> Result<TraitSet> {
        ratings.check(self.names, 5)?;
        let grid = RidgeVariant::grid(self.coords.ncols());
        self.trait_set(&ratings.traits, Method::Ridge, |t| {
            let (x, r) = rated_rows(self.coords, self.names, ratings, t)?;
            if self.options.ridge_lambda.is_some() {
                let (direction, _) = fit_ridge(&x, &r, &self.options)?;
                let cv = if self.cross_validate {
                    Some(spearman(&loo_ridge_scores(&x, &r, &self.options)?, &r))
                } else {
                    None
                };
                return Ok((direction, cv, None));
            }
            let (variant, _) = select_ridge(&x, &r, &grid)?;
            let cv = if self.cross_validate {
                Some(spearman(&nested_loo_scores(&x, &r, &grid)?.0, &r))
            } else {
                None
            };
            Ok((variant.fit(&x, &r)?, cv, Some(variant)))
        })
    }

    /// The trait set of `names`, each trait's direction and cross-validated score from `fit`.
    fn trait_set(
        &self,
        names: &[String],
        method: Method,
        fit: impl Fn(usize) -> Result<(Direction, Option<f64>, Option<RidgeVariant>)>,
    ) -> Result<TraitSet> {
        let traits = names
            .iter()
            .enumerate()
            .map(|(t, name)| {
                let (direction, cross_validated, variant) = fit(t)?;
                Ok(TraitVector {
                    name: name.clone(),
                    direction,
                    cross_validated,
                    variant,
                })
            })
            .collect::<Result<Vec<_>>>()?;
        Ok(TraitSet {
            space: self.space,
            dim: self.coords.ncols(),
            method,
            traits,
        })
    }
}

/// Angles (degrees) between the directions of the same trait in two sets.
pub fn angles(a: &TraitSet, b: &TraitSet) -> Vec<(String, f64)> {
    a.traits
        .iter()
        .filter_map(|t| {
            b.get(&t.name).ok().map(|u| {
                (
                    t.name.clone(),
                    Direction::angle_deg(&t.direction, &u.direction),
                )
            })
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_fold_mean_makes_weak_predictions_anti_correlated_and_scores_avoid_it() {
        use rand::{Rng, SeedableRng};
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(3);
        let n = 40;
        let x = DMatrix::from_fn(n, 5, |_, _| rng.gen_range(-1.0..1.0));
        let r: Vec<f64> = (0..n).map(|_| rng.gen_range(0.0..1.0)).collect();
        // A huge ridge: almost no signal is left in w, so the intercept decides.
        let opts = FitOptions {
            ridge_lambda: Some(1e6 * n as f64),
            ..FitOptions::default()
        };
        let pred = loo_ridge_predictions(&x, &r, &opts).unwrap();
        let score = loo_ridge_scores(&x, &r, &opts).unwrap();
        assert!(spearman(&pred, &r) < -0.99, "{}", spearman(&pred, &r));
        assert!(spearman(&score, &r).abs() < 0.6, "{}", spearman(&score, &r));
        // Same directions: a score and a prediction differ by the fold's intercept only.
        let (d, _) = fit_ridge(&x.clone().remove_row(0), &r[1..], &opts).unwrap();
        assert!((pred[0] - score[0] - d.b).abs() < 1e-12);
    }

    #[test]
    fn spearman_of_monotone_and_reversed_sequences() {
        let a = [1.0, 2.0, 3.0, 4.0, 5.0];
        let b = [0.1, 0.5, 0.7, 10.0, 11.0];
        assert!((spearman(&a, &b) - 1.0).abs() < 1e-12);
        let c: Vec<f64> = b.iter().rev().copied().collect();
        assert!((spearman(&a, &c) + 1.0).abs() < 1e-12);
        // Ties: scipy.stats.spearmanr([1,2,2,3],[1,3,2,4]) = 0.9486832980505138.
        let r = spearman(&[1.0, 2.0, 2.0, 3.0], &[1.0, 3.0, 2.0, 4.0]);
        assert!((r - 0.948_683_298_050_513_8).abs() < 1e-12, "{r}");
    }
}

#[cfg(test)]
mod kernel_tests {
    use super::*;

    #[test]
    fn kernel_ridge_recovers_a_smooth_non_linear_rating() {
        // r = sin(2x₀) + x₁², sampled on a seeded grid; LOO predictions track it closely,
        // which no linear score of (x₀, x₁) can do for the x₁² term.
        let n = 60;
        let x = DMatrix::from_fn(n, 2, |i, j| {
            let u = ((i * 37 + j * 11) % n) as f64 / n as f64;
            2.0 * u - 1.0
        });
        let r: Vec<f64> = (0..n)
            .map(|i| (2.0 * x[(i, 0)]).sin() + x[(i, 1)].powi(2))
            .collect();
        let p = loo_kernel_ridge_predictions(&x, &r, &KernelRidgeGrid::default()).unwrap();
        let rmse = (p.iter().zip(&r).map(|(a, b)| (a - b).powi(2)).sum::<f64>() / n as f64).sqrt();
        assert!(rmse < 0.1, "rmse {rmse}");
        assert!(spearman(&p, &r) > 0.95);
    }
}
