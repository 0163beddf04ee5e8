//! Beyond the thesis: a log-space PCA basis with optimised sample directions.

use nalgebra::{DMatrix, DVector, SymmetricEigen};
use rayon::prelude::*;

use crate::error::{Result, SamplingError};
use crate::grid::GridTable;
use crate::training::{from_log_clamped, measurable_rows, to_log, TrainingSet};

/// A log-space PCA model on a training grid, with optimised sample directions (beyond the
/// thesis).
///
/// Materials are modelled as `y = m + U a` in log space (`y = ln(max(f,0) + 10⁻³)`), `U` the
/// first `k` principal directions of the training corpus. A measured subset `S` of rows gives
/// `y_S − m_S = U_S a + e`. The coefficients get a Gaussian prior with the corpus variances
/// (`a_j ~ N(0, λ_j / N)`), and every row `r` its own error variance `σ_r²` = the corpus
/// residual variance of row `r` after `k` components plus the measurement noise variance. The
/// estimate is the posterior mean (a ridge regression, as in Nielsen et al. 2015).
///
/// Rows are chosen greedily to minimise the trace of the posterior covariance of `a`, which,
/// `U` being orthonormal, is the expected squared log-space reconstruction error in the model
/// (A-optimal design). Each step adds the row with the largest reduction
/// `‖P u‖² / (σ_r² + uᵀ P u)` and updates `P` by Sherman–Morrison.
///
/// # Examples
///
/// ```
/// use sampling::LogPcaModel;
/// use brdf::analytic::{BlinnPhong, Lambert};
/// use brdf::Brdf;
/// use sampling::{metrics, GridTable, SampleGrid, TrainingSet};
///
/// // Six analytic materials on a coarse sub-grid of the MERL grid.
/// let grid = SampleGrid::new(6, 6, 12).unwrap();
/// let training: Vec<Box<dyn Brdf>> = (0..6)
///     .map(|i| -> Box<dyn Brdf> {
///         let kd = [0.1 + 0.1 * i as f64, 0.3, 0.5 - 0.05 * i as f64];
///         if i < 3 {
///             Box::new(Lambert { kd })
///         } else {
///             Box::new(BlinnPhong { kd, ks: [0.3; 3], exponent: 10.0 * i as f64 })
///         }
///     })
///     .collect();
/// let set = TrainingSet::from_brdfs(&training, grid).unwrap();
/// let target = GridTable::tabulate(training[4].as_ref(), grid);
/// // Five components span the six materials about their mean.
/// let model = LogPcaModel::fit(&set, 5, 0.01).unwrap();
/// assert_eq!(model.dim(), 3 * grid.len());
/// // A training material projects and comes back.
/// let full = model.reconstruct(&model.project(&target).unwrap()).unwrap();
/// assert!(metrics::log_rms_relative(&target, &full).unwrap() < 1e-4);
/// // Greedy A-optimal rows: each addition lowers the expected error.
/// let (rows, trace) = model.select_rows(30).unwrap();
/// assert_eq!(rows.len(), 30);
/// assert!(trace.windows(2).all(|w| w[1] <= w[0]));
/// // Thirty measured values are enough to recover the material.
/// let measured: Vec<f64> = rows.iter().map(|&r| target.values[r]).collect();
/// let fitted = model.reconstruct(&model.fit_coefficients(&rows, &measured).unwrap()).unwrap();
/// let err = metrics::log_rms_relative(&target, &fitted).unwrap();
/// assert!(err < 5e-3, "relative log RMS error {err}");
/// ```
#[derive(Debug, Clone)]
pub struct LogPcaModel {
    /// The training grid.
    pub grid: crate::grid::SampleGrid,
    /// Mean log vector (length `dim`).
    pub mean: Vec<f64>,
    /// Basis, row-major `dim × k` (row `r` is `u_r`).
    pub basis: Vec<f64>,
    /// Number of components `k`.
    pub components: usize,
    /// Prior variance of each coefficient (`λ_j / N`).
    pub prior_variance: Vec<f64>,
    /// Corpus residual variance of each row after `k` components.
    pub residual_variance: Vec<f64>,
    /// Measurement noise variance in log space (`noise²` for multiplicative noise `exp(noise z)`).
    pub noise_variance: f64,
}

/// Rows per block of the blocked passes over the corpus in [`LogPcaModel::fit`].
const FIT_BLOCK: usize = 4096;

/// Log values of the rows `start..start + FIT_BLOCK` (clipped) of every material, centred by
/// `mean` (or by their own mean, which is returned), as an `N × rows` matrix.
fn centred_block(
    training: &TrainingSet,
    start: usize,
    mean: Option<&[f64]>,
) -> (DMatrix<f64>, Vec<f64>) {
    let n = training.len();
    let d = training.dim();
    let len = FIT_BLOCK.min(d - start);
    let mut b = DMatrix::<f64>::zeros(n, len);
    for m in 0..n {
        let src = &training.values[m * d + start..m * d + start + len];
        for (j, &v) in src.iter().enumerate() {
            b[(m, j)] = to_log(f64::from(v));
        }
    }
    let mean: Vec<f64> = match mean {
        Some(m) => m.to_vec(),
        None => (0..len).map(|j| b.column(j).sum() / n as f64).collect(),
    };
    for (j, mj) in mean.iter().enumerate() {
        for x in b.column_mut(j).iter_mut() {
            *x -= mj;
        }
    }
    (b, mean)
}

impl LogPcaModel {
    /// Fits `k` components to the training set.
    pub fn fit(training: &TrainingSet, k: usize, noise: f64) -> Result<Self> {
        let n = training.len();
        let d = training.dim();
        if n < 2 {
            return Err(SamplingError::InvalidParameter(
                "log PCA needs at least two materials".into(),
            ));
        }
        if k == 0 || k >= n {
            return Err(SamplingError::InvalidParameter(format!(
                "components {k} must be in 1..{n}"
            )));
        }
        if !(noise.is_finite() && noise >= 0.0) {
            return Err(SamplingError::InvalidParameter(format!("noise {noise}")));
        }
        // Pass 1, in blocks of rows: the mean log of every row and the Gram matrix of the
        // centred materials, without an f64 copy of the corpus.
        let starts: Vec<usize> = (0..d).step_by(FIT_BLOCK).collect();
        let pass1: Vec<(Vec<f64>, DMatrix<f64>)> = starts
            .par_iter()
            .map(|&start| {
                let (b, mean) = centred_block(training, start, None);
                let gram = &b * b.transpose();
                (mean, gram)
            })
            .collect();
        let mut mean = Vec::with_capacity(d);
        let mut gram = DMatrix::<f64>::zeros(n, n);
        for (m, g) in pass1 {
            mean.extend(m);
            gram += g;
        }
        let eig = SymmetricEigen::new(gram);
        let mut order: Vec<usize> = (0..n).collect();
        order.sort_by(|&a, &b| eig.eigenvalues[b].total_cmp(&eig.eigenvalues[a]));
        let lambdas: Vec<f64> = order.iter().map(|&i| eig.eigenvalues[i].max(0.0)).collect();
        if lambdas[k - 1] <= lambdas[0] * 1e-12 {
            return Err(SamplingError::InvalidParameter(format!(
                "corpus has fewer than {k} independent directions"
            )));
        }
        // u_j = Σ_m V_mj c_m / sqrt(λ_j): U = Cᵀ W with W = V Λ^{-1/2} (N × k).
        let w = DMatrix::from_fn(n, k, |m, j| {
            eig.eigenvectors[(m, order[j])] / lambdas[j].sqrt()
        });
        // Pass 2: the basis and, per row, the corpus residual variance after k components,
        // Σ_m e² = Σ_m c_m² − Σ_j λ_j u_j² (the fit is the orthogonal projection).
        let mut basis = vec![0.0; d * k];
        let mut residual_variance = vec![0.0; d];
        basis
            .par_chunks_mut(FIT_BLOCK * k)
            .zip(residual_variance.par_chunks_mut(FIT_BLOCK))
            .enumerate()
            .for_each(|(blk, (out, res))| {
                let start = blk * FIT_BLOCK;
                let (b, _) = centred_block(training, start, Some(&mean[start..start + res.len()]));
                let u = b.transpose() * &w;
                for (i, r) in res.iter_mut().enumerate() {
                    let mut fitted = 0.0;
                    for j in 0..k {
                        out[i * k + j] = u[(i, j)];
                        fitted += lambdas[j] * u[(i, j)] * u[(i, j)];
                    }
                    let total: f64 = b.column(i).iter().map(|c| c * c).sum();
                    *r = (total - fitted).max(0.0) / n as f64;
                }
            });
        let prior_variance: Vec<f64> = lambdas[..k].iter().map(|l| l / n as f64).collect();
        Ok(LogPcaModel {
            grid: training.grid,
            mean,
            basis,
            components: k,
            prior_variance,
            residual_variance,
            noise_variance: noise * noise,
        })
    }

    /// Values per material.
    pub fn dim(&self) -> usize {
        self.mean.len()
    }

    fn row(&self, r: usize) -> &[f64] {
        &self.basis[r * self.components..(r + 1) * self.components]
    }

    fn row_variance(&self, r: usize) -> f64 {
        self.residual_variance[r] + self.noise_variance + 1e-12
    }

    /// Greedy A-optimal choice of `n` distinct measurable rows. Returns the rows and the trace of the
    /// posterior covariance after each addition.
    pub fn select_rows(&self, n: usize) -> Result<(Vec<usize>, Vec<f64>)> {
        let d = self.dim();
        if n == 0 || n > d {
            return Err(SamplingError::InvalidParameter(format!(
                "cannot select {n} of {d} rows"
            )));
        }
        let k = self.components;
        let mut p = DMatrix::from_diagonal(&DVector::from_column_slice(&self.prior_variance));
        // Rows a planar sample cannot measure are never chosen.
        let mut chosen: Vec<bool> = measurable_rows(&self.grid).iter().map(|ok| !ok).collect();
        // Per row, ‖P u‖² and uᵀ P u, kept up to date by the rank-one updates of P, so that a
        // step costs O(d k) instead of O(d k²).
        let mut stats: Vec<(f64, f64)> = (0..d)
            .into_par_iter()
            .map(|r| {
                let u = self.row(r);
                let mut a = 0.0;
                let mut b = 0.0;
                for (uj, pj) in u.iter().zip(&self.prior_variance) {
                    a += (pj * uj) * (pj * uj);
                    b += pj * uj * uj;
                }
                (a, b)
            })
            .collect();
        let mut rows = Vec::with_capacity(n);
        let mut traces = Vec::with_capacity(n);
        for _ in 0..n {
            let best = stats
                .par_iter()
                .enumerate()
                .filter(|&(r, _)| !chosen[r])
                .map(|(r, &(a, b))| (a.max(0.0) / (self.row_variance(r) + b.max(0.0)), r))
                .reduce(
                    || (f64::NEG_INFINITY, usize::MAX),
                    |a, b| {
                        if b.0 > a.0 || (b.0 == a.0 && b.1 < a.1) {
                            b
                        } else {
                            a
                        }
                    },
                );
            let r = best.1;
            if r == usize::MAX {
                return Err(SamplingError::InvalidParameter(format!(
                    "only {} measurable rows",
                    rows.len()
                )));
            }
            let u = DVector::from_column_slice(self.row(r));
            let q = &p * &u;
            let denom = self.row_variance(r) + u.dot(&q);
            let pq = &p * &q;
            let qq = q.norm_squared();
            let (qs, pqs) = (q.as_slice(), pq.as_slice());
            stats.par_iter_mut().enumerate().for_each(|(i, st)| {
                let ui = &self.basis[i * k..(i + 1) * k];
                let mut t = 0.0;
                let mut s = 0.0;
                for j in 0..k {
                    t += qs[j] * ui[j];
                    s += pqs[j] * ui[j];
                }
                st.0 += -2.0 * t * s / denom + t * t * qq / (denom * denom);
                st.1 -= t * t / denom;
            });
            p -= &q * q.transpose() / denom;
            chosen[r] = true;
            rows.push(r);
            traces.push(p.trace());
        }
        Ok((rows, traces))
    }

    /// Posterior-mean coefficients from measured values `b` (1/sr) at `rows`.
    pub fn fit_coefficients(&self, rows: &[usize], b: &[f64]) -> Result<Vec<f64>> {
        if rows.len() != b.len() {
            return Err(SamplingError::Dimension(format!(
                "{} rows but {} values",
                rows.len(),
                b.len()
            )));
        }
        if rows.iter().any(|&r| r >= self.dim()) {
            return Err(SamplingError::Dimension(
                "row outside the model grid".into(),
            ));
        }
        if b.iter().any(|v| !v.is_finite()) {
            return Err(SamplingError::NonFinite("measured value".into()));
        }
        let k = self.components;
        let mut a = DMatrix::from_diagonal(&DVector::from_iterator(
            k,
            self.prior_variance.iter().map(|v| 1.0 / v),
        ));
        let mut rhs = DVector::zeros(k);
        for (&r, &v) in rows.iter().zip(b) {
            let u = DVector::from_column_slice(self.row(r));
            let w = 1.0 / self.row_variance(r);
            a += &u * u.transpose() * w;
            rhs += &u * (w * (to_log(v) - self.mean[r]));
        }
        let chol = a.cholesky().ok_or_else(|| {
            SamplingError::InvalidParameter("posterior precision not positive definite".into())
        })?;
        Ok(chol.solve(&rhs).iter().copied().collect())
    }

    /// `exp(m + U a) − 10⁻³` as a table on the model grid.
    pub fn reconstruct(&self, coefficients: &[f64]) -> Result<GridTable> {
        if coefficients.len() != self.components {
            return Err(SamplingError::Dimension(format!(
                "{} coefficients for {} components",
                coefficients.len(),
                self.components
            )));
        }
        let values: Vec<f64> = (0..self.dim())
            .into_par_iter()
            .map(|r| {
                let y = self.mean[r]
                    + self
                        .row(r)
                        .iter()
                        .zip(coefficients)
                        .map(|(u, a)| u * a)
                        .sum::<f64>();
                from_log_clamped(y)
            })
            .collect();
        GridTable::new(self.grid, values)
    }

    /// Projection of a full table (log space, least squares) — the best this basis can do.
    pub fn project(&self, table: &GridTable) -> Result<Vec<f64>> {
        if table.grid != self.grid {
            return Err(SamplingError::Dimension("table on another grid".into()));
        }
        let k = self.components;
        let mut a = vec![0.0; k];
        for r in 0..self.dim() {
            let y = to_log(table.values[r]) - self.mean[r];
            for (aj, u) in a.iter_mut().zip(self.row(r)) {
                *aj += u * y;
            }
        }
        Ok(a)
    }
}
