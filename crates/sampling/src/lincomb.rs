//! Linear combination of training BRDFs (thesis §6.5, eq. 6.13).
//!
//! A new material `b` is modelled as `Y c` with `Y` the matrix whose columns are the training
//! materials. The `n` rows of `Y` to measure are chosen by a greedy swap search that lowers the
//! ratio of the extreme eigenvalues of `XᵀX` (`X` = the selected rows); `c` is the
//! pseudo-inverse of `X` applied to the measured values.

use nalgebra::{DMatrix, DVector, SymmetricEigen};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rayon::prelude::*;

use crate::error::{Result, SamplingError};
use crate::grid::GridTable;
use crate::training::{measurable_rows, TrainingSet};

/// Settings of the greedy swap search.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SwapSearch {
    /// Number of proposed swaps.
    pub proposals: usize,
    /// Seed of the proposal stream.
    pub seed: u64,
}

impl Default for SwapSearch {
    fn default() -> Self {
        SwapSearch {
            proposals: 2000,
            seed: 1,
        }
    }
}

/// Outcome of a row selection.
#[derive(Debug, Clone, PartialEq)]
pub struct Selection {
    /// Selected rows (`channel × grid.len() + point`).
    pub rows: Vec<usize>,
    /// Eigenvalue ratio of the initial random set.
    pub initial_ratio: f64,
    /// Eigenvalue ratio after the search.
    pub final_ratio: f64,
    /// Accepted swaps.
    pub accepted: usize,
}

/// Ratio λmax/λmin of the non-trivial spectrum of `XᵀX`: with `n < N` rows it is computed on
/// `XXᵀ`, which has the same non-zero eigenvalues. Returns `∞` for a singular system.
pub fn eigenvalue_ratio(x: &DMatrix<f64>) -> f64 {
    let g = if x.nrows() >= x.ncols() {
        x.transpose() * x
    } else {
        x * x.transpose()
    };
    gram_ratio(g)
}

fn gram_ratio(g: DMatrix<f64>) -> f64 {
    let e = SymmetricEigen::new(g);
    let max = e.eigenvalues.max();
    let min = e.eigenvalues.min();
    let well_posed = max > 0.0 && min > max * 1e-15;
    if !well_posed {
        f64::INFINITY
    } else {
        max / min
    }
}

/// The training values of the given rows: an `rows.len() × N` matrix.
pub fn row_matrix(training: &TrainingSet, rows: &[usize]) -> DMatrix<f64> {
    let d = training.dim();
    DMatrix::from_fn(rows.len(), training.len(), |i, m| {
        f64::from(training.values[m * d + rows[i]])
    })
}

/// Greedy swap selection of `n` rows (§6.5) among the measurable ones (both directions above
/// the horizon). Starts from a seeded random set; each proposal swaps a random selected row
/// with a random unselected one and is kept only if the eigenvalue ratio decreases.
pub fn select_rows(training: &TrainingSet, n: usize, search: SwapSearch) -> Result<Selection> {
    let d = training.dim();
    let nm = training.len();
    if n == 0 || n > d {
        return Err(SamplingError::InvalidParameter(format!(
            "cannot select {n} of {d} rows"
        )));
    }
    if nm == 0 {
        return Err(SamplingError::InvalidParameter("empty training set".into()));
    }
    // Only rows a planar sample can measure are candidates.
    let candidates: Vec<usize> = measurable_rows(&training.grid)
        .iter()
        .enumerate()
        .filter_map(|(r, &ok)| ok.then_some(r))
        .collect();
    if n > candidates.len() {
        return Err(SamplingError::InvalidParameter(format!(
            "cannot select {n} of {} measurable rows",
            candidates.len()
        )));
    }
    let mut rng = ChaCha8Rng::seed_from_u64(search.seed);
    let mut chosen = vec![false; d];
    let mut rows = Vec::with_capacity(n);
    while rows.len() < n {
        let r = candidates[rng.gen_range(0..candidates.len())];
        if !chosen[r] {
            chosen[r] = true;
            rows.push(r);
        }
    }
    let row_vec = |r: usize| DVector::from_fn(nm, |m, _| f64::from(training.values[m * d + r]));
    let tall = n >= nm;
    let mut x = row_matrix(training, &rows);
    // Tall: keep XᵀX (N × N) and update by rank-one terms. Wide: rebuild the row of XXᵀ.
    let mut g = if tall {
        x.transpose() * &x
    } else {
        &x * x.transpose()
    };
    let initial_ratio = gram_ratio(g.clone());
    let mut ratio = initial_ratio;
    let mut accepted = 0;
    if n == candidates.len() {
        return Ok(Selection {
            rows,
            initial_ratio,
            final_ratio: ratio,
            accepted,
        });
    }
    for _ in 0..search.proposals {
        let pos = rng.gen_range(0..n);
        let cand = loop {
            let r = candidates[rng.gen_range(0..candidates.len())];
            if !chosen[r] {
                break r;
            }
        };
        let new_row = row_vec(cand);
        let trial = if tall {
            let old_row = x.row(pos).transpose();
            &g - &old_row * old_row.transpose() + &new_row * new_row.transpose()
        } else {
            let mut t = g.clone();
            let dots = &x * &new_row;
            for i in 0..n {
                t[(pos, i)] = dots[i];
                t[(i, pos)] = dots[i];
            }
            t[(pos, pos)] = new_row.norm_squared();
            t
        };
        let r = gram_ratio(trial.clone());
        if r < ratio {
            ratio = r;
            g = trial;
            chosen[rows[pos]] = false;
            chosen[cand] = true;
            rows[pos] = cand;
            x.set_row(pos, &new_row.transpose());
            accepted += 1;
        }
    }
    tracing::debug!(n, initial_ratio, ratio, accepted, "lincomb swap search");
    Ok(Selection {
        rows,
        initial_ratio,
        final_ratio: ratio,
        accepted,
    })
}

/// Coefficients `c = X⁺ b` of the linear combination from values `b` at `rows`.
pub fn fit_coefficients(training: &TrainingSet, rows: &[usize], b: &[f64]) -> Result<Vec<f64>> {
    if rows.len() != b.len() {
        return Err(SamplingError::Dimension(format!(
            "{} rows but {} values",
            rows.len(),
            b.len()
        )));
    }
    if rows.iter().any(|&r| r >= training.dim()) {
        return Err(SamplingError::Dimension(
            "row outside the training grid".into(),
        ));
    }
    if b.iter().any(|v| !v.is_finite()) {
        return Err(SamplingError::NonFinite("measured value".into()));
    }
    let x = row_matrix(training, rows);
    let svd = x.svd(true, true);
    let smax = svd.singular_values.max();
    let eps = smax * 1e-10 * (rows.len().max(training.len()) as f64);
    let c = svd
        .solve(&DVector::from_column_slice(b), eps)
        .map_err(|e| SamplingError::InvalidParameter(format!("pseudo-inverse failed: {e}")))?;
    Ok(c.iter().copied().collect())
}

/// `Y c`, clamped at 0, as a table on the training grid.
pub fn combine(training: &TrainingSet, coefficients: &[f64]) -> Result<GridTable> {
    if coefficients.len() != training.len() {
        return Err(SamplingError::Dimension(format!(
            "{} coefficients for {} materials",
            coefficients.len(),
            training.len()
        )));
    }
    let d = training.dim();
    let mut out = vec![0.0; d];
    // Blocks of rows in parallel; each block sums over the materials.
    out.par_chunks_mut(1 << 14)
        .enumerate()
        .for_each(|(blk, o)| {
            let start = blk << 14;
            for (m, &c) in coefficients.iter().enumerate() {
                let v = &training.material(m)[start..start + o.len()];
                for (oi, &vi) in o.iter_mut().zip(v) {
                    *oi += c * f64::from(vi);
                }
            }
            for oi in o.iter_mut() {
                *oi = oi.max(0.0);
            }
        });
    GridTable::new(training.grid, out)
}
