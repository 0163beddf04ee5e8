//! The unknown material as a non-negative combination of corpus materials (thesis §6.5).
//!
//! The thesis represents a new BRDF as a linear combination `b = Y c` of the measured ones,
//! one coefficient per material shared by the three channels. With `c ≥ 0` the combination is
//! valid wherever the photographs are silent: every corpus table is non-negative and
//! reciprocal, and so is any non-negative sum of them, and a convex combination of real
//! materials is itself manufacturable (§4.4). Because rendering is linear in the BRDF, each
//! photograph is the same combination of the corpus materials' renders, so the coefficients
//! are a small non-negative least-squares problem (one unknown per corpus material) over the
//! pixels' functionals, solved here by the active-set method of Lawson and Hanson on the
//! normal equations.

use nalgebra::{DMatrix, DVector};
use rayon::prelude::*;

use crate::error::{RecoverError, Result};
use crate::fit::{channel_epsilon, Observation};

/// Settings of [`fit_combination`].
#[derive(Debug, Clone, PartialEq)]
pub struct CombinationOptions {
    /// `ε` as a fraction of each channel's mean observed radiance (as in
    /// [`crate::FitOptions::epsilon_fraction`]): residuals are `ln(Î + ε) − ln(I + ε)`.
    pub epsilon_fraction: f64,
    /// Reweighted passes after the first (relative) least-squares pass, each weighing a pixel
    /// channel so that its squared error equals its squared log residual at the previous
    /// solution.
    pub log_passes: usize,
    /// Keep the coefficients' sum at 1 (a penalty `μ (Σ c − 1)²` far heavier than the data):
    /// the material is then a convex combination, inside the corpus's hull (thesis §4.4).
    pub convex: bool,
    /// Scale the table down when its directional albedo exceeds 1 (as
    /// [`crate::RecoverOptions::enforce_albedo`]).
    pub enforce_albedo: bool,
}

impl Default for CombinationOptions {
    fn default() -> Self {
        CombinationOptions {
            epsilon_fraction: 0.01,
            log_passes: 3,
            convex: false,
            enforce_albedo: true,
        }
    }
}

/// A material found as a non-negative combination of corpus materials.
#[derive(Debug, Clone)]
pub struct Combination {
    /// Coefficient of every corpus material (corpus order), all ≥ 0.
    pub coefficients: Vec<f64>,
    /// The combined table `Σ c_m f_m` (scaled by `albedo_scale`).
    pub table: brdf::MerlTable,
    /// Largest directional albedo per channel before any scaling.
    pub max_albedo: [f64; 3],
    /// Factor the table was scaled by to keep the albedo ≤ 1 (1 = none).
    pub albedo_scale: f64,
    /// RMS log residual of each observation.
    pub residual_rms: Vec<f64>,
}

impl Combination {
    /// The materials with a non-zero coefficient, largest first.
    pub fn used<'n>(&self, names: &'n [String]) -> Vec<(&'n str, f64)> {
        let mut v: Vec<(&str, f64)> = names
            .iter()
            .zip(&self.coefficients)
            .filter(|(_, &c)| c > 0.0)
            .map(|(n, &c)| (n.as_str(), c))
            .collect();
        v.sort_by(|a, b| b.1.total_cmp(&a.1));
        v
    }
}

/// Fits the observations with a non-negative combination of the materials of `corpus`
/// (tables on the MERL grid, stored in log space as `reduce` keeps them).
///
/// # Examples
///
/// ```
/// use recover::{fit_combination, CombinationOptions, FunctionalOptions, Functionals};
/// use recover::{Observation, Photo, RecoveryScene};
/// // Three analytic materials, and a photograph of a 30 % / 70 % mix of the first two.
/// let specs = ["lambert:kd=0.6/0.3/0.2", "ggx:alpha=0.15,kd=0.05,ks=0.5", "lambert:kd=0.1/0.4/0.7"];
/// let mut corpus = reduce::Corpus::new(reduce::MATERIAL_DIM);
/// for s in specs {
///     corpus.push_values(s, &brdf::load(s).unwrap().tabulate().values()).unwrap();
/// }
/// let a = brdf::load(specs[0]).unwrap().tabulate().values();
/// let b = brdf::load(specs[1]).unwrap().tabulate().values();
/// let mix: Vec<f64> = a.iter().zip(&b).map(|(x, y)| 0.3 * x + 0.7 * y).collect();
/// let truth = brdf::MerlTable::from_values(mix).unwrap();
/// let scene = RecoveryScene::unit_sphere(24, &RecoveryScene::point_light_toml([2.0, 2.0, 4.0], 25.0)).unwrap();
/// let f = Functionals::build(&scene, &FunctionalOptions::default()).unwrap();
/// let mut pixels = vec![[0.0f32; 3]; 24 * 24];
/// for (&p, v) in f.pixels.iter().zip(f.apply_table(&truth)) {
///     pixels[p as usize] = v.map(|x| x as f32);
/// }
/// let obs = vec![Observation::new(f, &Photo::new(24, 24, pixels).unwrap(), None).unwrap()];
/// let found = fit_combination(&corpus, &obs, &CombinationOptions::default()).unwrap();
/// let c = &found.coefficients;
/// assert!((c[0] - 0.3).abs() < 0.01 && (c[1] - 0.7).abs() < 0.01 && c[2] < 0.01, "{c:?}");
/// assert!(found.table.values().iter().all(|v| *v >= 0.0));
/// ```
pub fn fit_combination(
    corpus: &reduce::Corpus,
    observations: &[Observation],
    options: &CombinationOptions,
) -> Result<Combination> {
    let design = Design::new(corpus, observations, options.epsilon_fraction)?;
    let c = design.solve(&vec![true; design.targets.len()], options)?;
    let mut sums = vec![(0.0, 0usize); observations.len()];
    for (t, l) in design.targets.iter().zip(design.log_residuals(&c)) {
        sums[t.observation].0 += l * l;
        sums[t.observation].1 += 1;
    }
    let residual_rms = sums
        .iter()
        .map(|&(s, n)| (s / n.max(1) as f64).sqrt())
        .collect();
    let coefficients: Vec<f64> = c.iter().map(|v| v.max(0.0)).collect();
    let mut table = combine(corpus, &coefficients)?;
    let (max_albedo, albedo_scale) = crate::limit_albedo(&mut table, options.enforce_albedo);
    Ok(Combination {
        coefficients,
        table,
        max_albedo,
        albedo_scale,
        residual_rms,
    })
}

/// Held-out RMS log residual of the combination in a two-fold cross-validation over the rows
/// (`folds[f][observation][row]`: whether the row is in fold `f`): fitted on one fold, scored
/// on the other, the mean square over observations averaged over both folds, as
/// [`crate::recover`] scores its candidate `k`.
pub fn cross_validate_combination(
    corpus: &reduce::Corpus,
    observations: &[Observation],
    options: &CombinationOptions,
    folds: &[Vec<Vec<bool>>; 2],
) -> Result<f64> {
    let design = Design::new(corpus, observations, options.epsilon_fraction)?;
    let in_fold = |f: usize| -> Vec<bool> {
        design
            .targets
            .iter()
            .map(|t| folds[f][t.observation].get(t.row).copied().unwrap_or(false))
            .collect()
    };
    let mut s2 = 0.0;
    for f in 0..2 {
        let c = design.solve(&in_fold(f), options)?;
        let test = in_fold(1 - f);
        let mut sums = vec![(0.0, 0usize); observations.len()];
        for ((t, l), &used) in design
            .targets
            .iter()
            .zip(design.log_residuals(&c))
            .zip(&test)
        {
            if used {
                sums[t.observation].0 += l * l;
                sums[t.observation].1 += 1;
            }
        }
        s2 +=
            sums.iter().map(|&(s, n)| s / n.max(1) as f64).sum::<f64>() / observations.len() as f64;
    }
    Ok((s2 / 2.0).sqrt())
}

/// One usable pixel channel.
struct Target {
    observation: usize,
    row: usize,
    /// Observed radiance.
    observed: f64,
    /// The channel's `ε`.
    epsilon: f64,
}

/// The least-squares problem: every corpus material rendered through the functionals (one
/// column each) against the observed pixel channels (one row each).
struct Design {
    targets: Vec<Target>,
    a: DMatrix<f64>,
    b: DVector<f64>,
}

impl Design {
    fn new(
        corpus: &reduce::Corpus,
        observations: &[Observation],
        epsilon_fraction: f64,
    ) -> Result<Design> {
        if corpus.is_empty() || corpus.dim() != brdf::MATERIAL_DIM {
            return Err(RecoverError::InvalidParameter(format!(
                "the combination needs corpus tables on the MERL grid ({} values each); got {} \
                 materials of {} values",
                brdf::MATERIAL_DIM,
                corpus.len(),
                corpus.dim()
            )));
        }
        if observations.is_empty() {
            return Err(RecoverError::InvalidParameter(
                "no photograph to fit".into(),
            ));
        }
        let m = corpus.len();
        let bins = brdf::BINS;
        let mut targets = Vec::new();
        let mut channels = Vec::new();
        for (oi, o) in observations.iter().enumerate() {
            let eps = channel_epsilon(o, epsilon_fraction);
            for (r, (v, u)) in o.observed.iter().zip(&o.usable).enumerate() {
                for c in 0..3 {
                    if u[c] {
                        targets.push(Target {
                            observation: oi,
                            row: r,
                            observed: v[c],
                            epsilon: eps[c],
                        });
                        channels.push(c);
                    }
                }
            }
        }
        if targets.is_empty() {
            return Err(RecoverError::InvalidParameter(
                "the photographs have no usable pixel".into(),
            ));
        }
        let mut a = DMatrix::zeros(targets.len(), m);
        for i in 0..m {
            let row = corpus.row(i);
            let renders: Vec<Vec<[f64; 3]>> = observations
                .iter()
                .map(|o| {
                    o.functionals.apply(|b| {
                        let b = b as usize;
                        [0, 1, 2].map(|c| reduce::from_log(row[c * bins + b]).max(0.0))
                    })
                })
                .collect();
            for (t, (target, &c)) in targets.iter().zip(&channels).enumerate() {
                a[(t, i)] = renders[target.observation][target.row][c];
            }
        }
        let b = DVector::from_iterator(targets.len(), targets.iter().map(|t| t.observed));
        Ok(Design { targets, a, b })
    }

    /// `ln(Î + ε) − ln(I + ε)` of every target for coefficients `c`.
    fn log_residuals(&self, c: &DVector<f64>) -> Vec<f64> {
        let pred = &self.a * c;
        self.targets
            .iter()
            .zip(pred.iter())
            .map(|(t, &p)| (p.max(0.0) + t.epsilon).ln() - (t.observed + t.epsilon).ln())
            .collect()
    }

    /// The coefficients fitted to the targets marked in `rows`: relative least squares first
    /// (weight `1/(I + ε)²`), then [`CombinationOptions::log_passes`] reweighted passes.
    fn solve(&self, rows: &[bool], options: &CombinationOptions) -> Result<DVector<f64>> {
        let keep = |t: usize, w: f64| if rows[t] { w } else { 0.0 };
        let w: Vec<f64> = self
            .targets
            .iter()
            .enumerate()
            .map(|(t, x)| keep(t, 1.0 / (x.observed + x.epsilon).powi(2)))
            .collect();
        let mut c = weighted_nnls(&self.a, &self.b, &w, options.convex)?;
        for _ in 0..options.log_passes {
            let pred = &self.a * &c;
            let w: Vec<f64> = self
                .targets
                .iter()
                .zip(pred.iter())
                .enumerate()
                .map(|(t, (x, &p))| {
                    let (i, e) = (x.observed, x.epsilon);
                    let d = p.max(0.0) - i;
                    let l = (p.max(0.0) + e).ln() - (i + e).ln();
                    let w = if d.abs() > 1e-12 * (i + e) {
                        (l / d).powi(2)
                    } else {
                        1.0 / (i + e).powi(2)
                    };
                    keep(t, w)
                })
                .collect();
            c = weighted_nnls(&self.a, &self.b, &w, options.convex)?;
        }
        Ok(c)
    }
}

/// The table `Σ c_m f_m` of the corpus materials (values in 1/sr).
pub fn combine(corpus: &reduce::Corpus, coefficients: &[f64]) -> Result<brdf::MerlTable> {
    if coefficients.len() != corpus.len() {
        return Err(RecoverError::InvalidParameter(format!(
            "{} coefficients for {} corpus materials",
            coefficients.len(),
            corpus.len()
        )));
    }
    let used: Vec<(usize, f64)> = coefficients
        .iter()
        .copied()
        .enumerate()
        .filter(|&(_, c)| c > 0.0)
        .collect();
    let values: Vec<f64> = (0..corpus.dim())
        .into_par_iter()
        .map(|d| {
            used.iter()
                .map(|&(i, c)| c * reduce::from_log(corpus.row(i)[d]).max(0.0))
                .sum()
        })
        .collect();
    Ok(brdf::MerlTable::from_values(values)?)
}

/// `argmin_{x ≥ 0} Σ_t w_t (a_t·x − b_t)²` (plus `μ (Σ x − 1)²` when `convex`).
fn weighted_nnls(
    a: &DMatrix<f64>,
    b: &DVector<f64>,
    w: &[f64],
    convex: bool,
) -> Result<DVector<f64>> {
    const CHUNK: usize = 4096;
    let n = a.ncols();
    let starts: Vec<usize> = (0..a.nrows()).step_by(CHUNK).collect();
    // The normal equations AᵀWA and AᵀWb, summed over blocks of rows in parallel.
    let (mut g, mut h) = starts
        .into_par_iter()
        .map(|s| {
            let rows = CHUNK.min(a.nrows() - s);
            let block = a.rows(s, rows);
            let mut weighted = block.clone_owned();
            for r in 0..rows {
                let wr = w[s + r];
                weighted.row_mut(r).iter_mut().for_each(|v| *v *= wr);
            }
            (block.tr_mul(&weighted), weighted.tr_mul(&b.rows(s, rows)))
        })
        .reduce(
            || (DMatrix::<f64>::zeros(n, n), DVector::<f64>::zeros(n)),
            |(g1, h1), (g2, h2)| (g1 + g2, h1 + h2),
        );
    if convex {
        let mu = 1e4 * g.diagonal().max().max(1e-300);
        g.add_scalar_mut(mu);
        h.add_scalar_mut(mu);
    }
    nnls_normal(&g, &h)
}

/// Lawson–Hanson active-set solution of `argmin_{x ≥ 0} ½ xᵀ G x − hᵀ x` (`G` symmetric
/// positive semi-definite, the normal equations of a least-squares problem).
pub(crate) fn nnls_normal(g: &DMatrix<f64>, h: &DVector<f64>) -> Result<DVector<f64>> {
    let n = h.len();
    let scale = g
        .diagonal()
        .iter()
        .fold(0.0f64, |a, &v| a.max(v.abs()))
        .max(1e-300);
    // A ridge far below the problem's scale keeps the passive subsystems solvable when two
    // materials render alike.
    let ridge = 1e-12 * scale;
    let tol = 1e-12 * h.amax().max(scale);
    let mut x = DVector::<f64>::zeros(n);
    let mut passive = vec![false; n];
    let solve = |passive: &[bool]| -> Option<DVector<f64>> {
        let idx: Vec<usize> = (0..n).filter(|&i| passive[i]).collect();
        let k = idx.len();
        let gp = DMatrix::from_fn(k, k, |r, c| {
            g[(idx[r], idx[c])] + if r == c { ridge } else { 0.0 }
        });
        let hp = DVector::from_fn(k, |r, _| h[idx[r]]);
        let s = gp.cholesky()?.solve(&hp);
        let mut z = DVector::zeros(n);
        for (r, &i) in idx.iter().enumerate() {
            z[i] = s[r];
        }
        Some(z)
    };
    for _ in 0..(3 * n + 10) {
        let grad = h - g * &x;
        let next = (0..n)
            .filter(|&i| !passive[i])
            .max_by(|&a, &b| grad[a].total_cmp(&grad[b]));
        let Some(j) = next.filter(|&j| grad[j] > tol) else {
            return Ok(x);
        };
        passive[j] = true;
        loop {
            let z = solve(&passive).ok_or_else(|| {
                RecoverError::InvalidParameter(
                    "the combination's normal equations are singular".into(),
                )
            })?;
            if (0..n).all(|i| !passive[i] || z[i] > 0.0) {
                x = z;
                break;
            }
            // Step from x towards z until the first passive coefficient reaches zero.
            let alpha = (0..n)
                .filter(|&i| passive[i] && z[i] <= 0.0)
                .map(|i| x[i] / (x[i] - z[i]))
                .fold(1.0f64, f64::min);
            x += (z - &x) * alpha;
            for i in 0..n {
                if passive[i] && x[i] <= tol.min(1e-15) {
                    passive[i] = false;
                    x[i] = 0.0;
                }
            }
        }
    }
    Ok(x)
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{Rng, SeedableRng};

    /// Projected gradient descent, slow but independent of the active-set logic.
    fn projected_gradient(g: &DMatrix<f64>, h: &DVector<f64>) -> DVector<f64> {
        let l = g.symmetric_eigenvalues().max();
        let mut x = DVector::zeros(h.len());
        for _ in 0..200_000 {
            let grad = g * &x - h;
            x = (&x - grad / l).map(|v| v.max(0.0));
        }
        x
    }

    #[test]
    fn the_active_set_solution_matches_projected_gradient_and_the_kkt_conditions() {
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(11);
        for case in 0..20 {
            let (rows, n) = (30, 8);
            let a = DMatrix::from_fn(rows, n, |_, _| rng.gen_range(-1.0..1.0));
            let b = DVector::from_fn(rows, |_, _| rng.gen_range(-1.0..1.0));
            let g = a.transpose() * &a;
            let h = a.transpose() * &b;
            let x = nnls_normal(&g, &h).unwrap();
            let reference = projected_gradient(&g, &h);
            assert!(
                (&x - &reference).amax() < 1e-6,
                "case {case}: {x} vs {reference}"
            );
            // KKT: x ≥ 0, gradient zero on the support and non-negative off it.
            let grad = &g * &x - &h;
            for i in 0..n {
                assert!(x[i] >= 0.0);
                if x[i] > 0.0 {
                    assert!(grad[i].abs() < 1e-9, "case {case}: {grad}");
                } else {
                    assert!(grad[i] > -1e-9, "case {case}: {grad}");
                }
            }
        }
    }

    #[test]
    fn the_weighted_problem_over_several_row_blocks_is_the_weighted_least_squares() {
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(5);
        let (rows, n) = (9_000, 6);
        let a = DMatrix::from_fn(rows, n, |_, _| rng.gen_range(0.0..1.0));
        let b = DVector::from_fn(rows, |_, _| rng.gen_range(0.0..2.0));
        let w: Vec<f64> = (0..rows).map(|_| rng.gen_range(0.1..3.0)).collect();
        // The normal equations formed row by row, without blocks.
        let mut g = DMatrix::<f64>::zeros(n, n);
        let mut h = DVector::<f64>::zeros(n);
        for t in 0..rows {
            let r = a.row(t).transpose();
            g += &r * r.transpose() * w[t];
            h += &r * (w[t] * b[t]);
        }
        let x = weighted_nnls(&a, &b, &w, false).unwrap();
        let reference = nnls_normal(&g, &h).unwrap();
        assert!((&x - &reference).amax() < 1e-9, "{x} vs {reference}");
        // The convex variant sums to 1.
        let c = weighted_nnls(&a, &b, &w, true).unwrap();
        assert!((c.sum() - 1.0).abs() < 1e-3, "{c}");
        assert!(c.iter().all(|v| *v >= 0.0));
    }

    #[test]
    fn an_unconstrained_optimum_inside_the_orthant_is_returned_as_is() {
        let g = DMatrix::from_row_slice(2, 2, &[2.0, 0.5, 0.5, 1.0]);
        let x_true = DVector::from_vec(vec![0.3, 1.2]);
        let h = &g * &x_true;
        let x = nnls_normal(&g, &h).unwrap();
        assert!((x - x_true).amax() < 1e-9);
    }
}
