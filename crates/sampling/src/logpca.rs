//! Beyond the seed: a log-space PCA basis with optimised sample directions.
//!
//! Materials are modelled as `y = m + U a` in log space (`y = ln(max(f,0) + 10⁻³)`), `U` the
//! first `k` principal directions of the training corpus. A measured subset `S` of rows gives
//! `y_S − m_S = U_S a + e`. The coefficients get a Gaussian prior with the corpus variances
//! (`a_j ~ N(0, λ_j / N)`), and every row `r` its own error variance `σ_r²` = the corpus
//! residual variance of row `r` after `k` components plus the measurement noise variance. The
//! estimate is the posterior mean (a ridge regression, as in Nielsen et al. 2015).
//!
//! Rows are chosen greedily to minimise the trace of the posterior covariance of `a`, which,
//! `U` being orthonormal, is the expected squared log-space reconstruction error in the model
//! (A-optimal design). Each step adds the row with the largest reduction
//! `‖P u‖² / (σ_r² + uᵀ P u)` and updates `P` by Sherman–Morrison.

use nalgebra::{DMatrix, DVector, SymmetricEigen};
use rayon::prelude::*;

use crate::error::{Result, SamplingError};
use crate::grid::GridTable;
use crate::training::{from_log, measurable_rows, to_log, TrainingSet};

/// A log-space PCA model on a training grid.
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
        let logs: Vec<f64> = training.values.par_iter().map(|&v| to_log(v)).collect();
        let mut mean = vec![0.0; d];
        for m in 0..n {
            for (s, v) in mean.iter_mut().zip(&logs[m * d..(m + 1) * d]) {
                *s += v;
            }
        }
        mean.iter_mut().for_each(|s| *s /= n as f64);
        let centred: Vec<f64> = logs
            .par_chunks(d)
            .flat_map_iter(|row| row.iter().zip(&mean).map(|(v, m)| v - m))
            .collect();
        // Gram matrix of the centred materials.
        let gram = DMatrix::from_fn(n, n, |i, j| {
            let a = &centred[i * d..(i + 1) * d];
            let b = &centred[j * d..(j + 1) * d];
            a.iter().zip(b).map(|(x, y)| x * y).sum::<f64>()
        });
        let eig = SymmetricEigen::new(gram);
        let mut order: Vec<usize> = (0..n).collect();
        order.sort_by(|&a, &b| eig.eigenvalues[b].total_cmp(&eig.eigenvalues[a]));
        let lambdas: Vec<f64> = order.iter().map(|&i| eig.eigenvalues[i].max(0.0)).collect();
        if lambdas[k - 1] <= lambdas[0] * 1e-12 {
            return Err(SamplingError::InvalidParameter(format!(
                "corpus has fewer than {k} independent directions"
            )));
        }
        // u_j = Σ_m V_mj c_m / sqrt(λ_j), stored row-major dim × k.
        let mut basis = vec![0.0; d * k];
        basis.par_chunks_mut(k).enumerate().for_each(|(r, out)| {
            for (j, o) in out.iter_mut().enumerate() {
                let col = order[j];
                let mut s = 0.0;
                for m in 0..n {
                    s += eig.eigenvectors[(m, col)] * centred[m * d + r];
                }
                *o = s / lambdas[j].sqrt();
            }
        });
        let prior_variance: Vec<f64> = lambdas[..k].iter().map(|l| l / n as f64).collect();
        // Residual variance per row over the corpus.
        let residual_variance: Vec<f64> = (0..d)
            .into_par_iter()
            .map(|r| {
                let u = &basis[r * k..(r + 1) * k];
                let mut s = 0.0;
                for m in 0..n {
                    let mut fit = 0.0;
                    for j in 0..k {
                        // Coordinate of material m on component j: sqrt(λ_j) V_mj.
                        fit += u[j] * lambdas[j].sqrt() * eig.eigenvectors[(m, order[j])];
                    }
                    let e = centred[m * d + r] - fit;
                    s += e * e;
                }
                s / n as f64
            })
            .collect();
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
        let mut p = DMatrix::from_diagonal(&DVector::from_column_slice(&self.prior_variance));
        // Rows a planar sample cannot measure are never chosen.
        let mut chosen: Vec<bool> = measurable_rows(&self.grid).iter().map(|ok| !ok).collect();
        let mut rows = Vec::with_capacity(n);
        let mut traces = Vec::with_capacity(n);
        for _ in 0..n {
            let pm = &p;
            let best = (0..d)
                .into_par_iter()
                .filter(|&r| !chosen[r])
                .map(|r| {
                    let u = DVector::from_column_slice(self.row(r));
                    let pu = pm * &u;
                    let gain = pu.norm_squared() / (self.row_variance(r) + u.dot(&pu));
                    (gain, r)
                })
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
            let pu = &p * &u;
            let denom = self.row_variance(r) + u.dot(&pu);
            p -= &pu * pu.transpose() / denom;
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
                from_log(y)
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
