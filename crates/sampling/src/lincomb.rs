//! Linear combination of training BRDFs (thesis §6.5, eq. 6.13).

use nalgebra::{DMatrix, DVector, SymmetricEigen};
use rand::distributions::{Distribution, WeightedIndex};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rayon::prelude::*;

use crate::error::{Result, SamplingError};
use crate::grid::GridTable;
use crate::training::{measurable_rows, TrainingSet};

/// The coordinates in which the swap search measures the conditioning of `XᵀX`.
///
/// The eigenvalue ratio of `XᵀX` depends on how the coefficients `c` are parametrised, while
/// the least-squares fit does not. With the raw training materials as coordinates (the thesis's
/// choice), rows with large values, such as the specular peaks, raise λmax, so the search
/// avoids exactly the rows that carry most of a glossy material's energy.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum SearchBasis {
    /// Coefficients of the training materials, as in the thesis.
    #[default]
    Materials,
    /// Coefficients whitened by the corpus: `c = W a` with `Wᵀ (YᵀY) W ≈ I` over all
    /// measurable rows (eigenvalues below 10⁻¹⁰ λmax are floored there). In these coordinates
    /// the full set of rows has ratio 1, and a subset has a ratio near 1 exactly when its
    /// Gram matrix has the shape of the full one, that is, when the fit on the subset
    /// behaves like the fit on the whole table. The initial set and every proposed row are
    /// drawn with probability proportional to the row's leverage `‖Wᵀ y_r‖²`.
    Whitened,
}

/// Settings of the greedy swap search.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SwapSearch {
    /// Number of proposed swaps.
    pub proposals: usize,
    /// Seed of the initial set and of the proposals.
    pub seed: u64,
    /// Coordinates of the conditioning criterion.
    pub basis: SearchBasis,
}

impl Default for SwapSearch {
    fn default() -> Self {
        SwapSearch {
            proposals: 2000,
            seed: 1,
            basis: SearchBasis::Materials,
        }
    }
}

/// Scale of each equation of `Y c ≈ b`. Scaling an equation does not change an exact solution,
/// only which errors the least-squares fit and the conditioning criterion weigh most.
#[derive(Debug, Clone, PartialEq)]
pub enum RowWeights {
    /// Every equation as measured (absolute error in 1/sr): specular peaks dominate.
    Unit,
    /// One weight per row of the training grid.
    PerRow(Vec<f64>),
}

impl RowWeights {
    /// Relative equations: each row divided by the corpus mean of that row plus the log floor
    /// (10⁻³), so every equation measures a relative error.
    pub fn relative(training: &TrainingSet) -> RowWeights {
        let d = training.dim();
        let nm = training.len().max(1) as f64;
        let mut sum = vec![0.0f64; d];
        for m in 0..training.len() {
            sum.par_iter_mut()
                .zip(training.material(m).par_iter())
                .for_each(|(s, &v)| *s += f64::from(v.max(0.0)));
        }
        RowWeights::PerRow(
            sum.into_iter()
                .map(|s| 1.0 / (s / nm + crate::training::LOG_FLOOR))
                .collect(),
        )
    }

    /// Weight of row `r`.
    #[inline]
    pub fn get(&self, r: usize) -> f64 {
        match self {
            RowWeights::Unit => 1.0,
            RowWeights::PerRow(w) => w[r],
        }
    }

    fn check(&self, d: usize) -> Result<()> {
        match self {
            RowWeights::Unit => Ok(()),
            RowWeights::PerRow(w) if w.len() != d => Err(SamplingError::Dimension(format!(
                "{} row weights for {d} rows",
                w.len()
            ))),
            RowWeights::PerRow(w) if w.iter().any(|v| !(v.is_finite() && *v > 0.0)) => Err(
                SamplingError::InvalidParameter("row weights must be finite and positive".into()),
            ),
            RowWeights::PerRow(_) => Ok(()),
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
    weighted_row_matrix(training, rows, &RowWeights::Unit)
}

/// The training values of the given rows, each scaled by its weight.
fn weighted_row_matrix(training: &TrainingSet, rows: &[usize], w: &RowWeights) -> DMatrix<f64> {
    let d = training.dim();
    DMatrix::from_fn(rows.len(), training.len(), |i, m| {
        f64::from(training.values[m * d + rows[i]]) * w.get(rows[i])
    })
}

/// Greedy swap selection of `n` rows (thesis §6.5) among the measurable ones (both directions
/// above the horizon), with unweighted equations.
///
/// This is the sample choice of the linear-combination method (thesis eq. 6.13).
/// A new material `b` is modelled as `Y c` with `Y` the matrix whose columns are the training
/// materials. The `n` rows of `Y` to measure are chosen by a greedy swap search that lowers the
/// ratio of the extreme eigenvalues of `XᵀX` (`X` = the selected rows); `c` is the
/// pseudo-inverse of `X` applied to the measured values.
pub fn select_rows(training: &TrainingSet, n: usize, search: SwapSearch) -> Result<Selection> {
    select_rows_weighted(training, n, search, &RowWeights::Unit)
}

/// Greedy swap selection of `n` rows (§6.5) among the measurable ones, for the equations scaled
/// by `weights`. Starts from a seeded random set; a swap is kept only if it lowers the
/// eigenvalue ratio of the scaled rows.
pub fn select_rows_weighted(
    training: &TrainingSet,
    n: usize,
    search: SwapSearch,
    weights: &RowWeights,
) -> Result<Selection> {
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
    weights.check(d)?;
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
    let (transform, sampler) = match search.basis {
        SearchBasis::Materials => (None, None),
        SearchBasis::Whitened => {
            let w = whitening(training, weights, &candidates);
            let lev = leverages(training, weights, &candidates, &w);
            let sampler = WeightedIndex::new(&lev).map_err(|e| {
                SamplingError::InvalidParameter(format!("no row has leverage: {e}"))
            })?;
            (Some(w), Some(sampler))
        }
    };
    let mut state = SearchState::new(
        training,
        weights,
        transform,
        &candidates,
        sampler.as_ref(),
        n,
        &mut rng,
    );
    let initial_ratio = state.ratio;
    if n < candidates.len() {
        state.search(&candidates, sampler.as_ref(), search.proposals, &mut rng);
    }
    tracing::debug!(
        n,
        initial_ratio,
        ratio = state.ratio,
        accepted = state.accepted,
        "lincomb swap search"
    );
    Ok(Selection {
        rows: state.rows,
        initial_ratio,
        final_ratio: state.ratio,
        accepted: state.accepted,
    })
}

/// The rows of the training matrix, scaled by their weights, in blocks of contiguous rows:
/// calls `f(first_row, block)` with `block` of size `len × N`.
fn for_row_blocks<T: Send>(
    training: &TrainingSet,
    weights: &RowWeights,
    f: impl Fn(usize, &DMatrix<f64>) -> T + Sync,
) -> Vec<T> {
    const BLOCK: usize = 4096;
    let d = training.dim();
    let nm = training.len();
    (0..d.div_ceil(BLOCK))
        .into_par_iter()
        .map(|b| {
            let start = b * BLOCK;
            let len = BLOCK.min(d - start);
            let mut block = DMatrix::<f64>::zeros(len, nm);
            for m in 0..nm {
                let v = &training.material(m)[start..start + len];
                for (i, &y) in v.iter().enumerate() {
                    block[(i, m)] = f64::from(y) * weights.get(start + i);
                }
            }
            f(start, &block)
        })
        .collect()
}

/// `W` with `Wᵀ G W = I` on the well-determined eigenspace of the corpus Gram matrix
/// `G = Σ y_r y_rᵀ` over the candidate rows (eigenvalues floored at 10⁻¹⁰ λmax).
fn whitening(training: &TrainingSet, weights: &RowWeights, candidates: &[usize]) -> DMatrix<f64> {
    let nm = training.len();
    let mut is_candidate = vec![false; training.dim()];
    for &r in candidates {
        is_candidate[r] = true;
    }
    let grams = for_row_blocks(training, weights, |start, block| {
        let mut g = DMatrix::<f64>::zeros(nm, nm);
        for i in 0..block.nrows() {
            if is_candidate[start + i] {
                let y = block.row(i);
                g.ger(1.0, &y.transpose(), &y.transpose(), 1.0);
            }
        }
        g
    });
    let g = grams
        .into_iter()
        .fold(DMatrix::<f64>::zeros(nm, nm), |a, b| a + b);
    let e = SymmetricEigen::new(g);
    let floor = e.eigenvalues.max().max(f64::MIN_POSITIVE) * 1e-10;
    let scale = DMatrix::from_diagonal(&e.eigenvalues.map(|l| 1.0 / l.max(floor).sqrt()));
    &e.eigenvectors * scale
}

/// Leverage `‖Wᵀ y_r‖²` of every candidate row, in the order of `candidates`.
fn leverages(
    training: &TrainingSet,
    weights: &RowWeights,
    candidates: &[usize],
    w: &DMatrix<f64>,
) -> Vec<f64> {
    let all: Vec<f64> = for_row_blocks(training, weights, |_, block| {
        let z = block * w;
        z.row_iter().map(|r| r.norm_squared()).collect::<Vec<_>>()
    })
    .into_iter()
    .flatten()
    .collect();
    candidates.iter().map(|&r| all[r]).collect()
}

/// The current selection of the swap search and its Gram matrix.
struct SearchState<'a> {
    training: &'a TrainingSet,
    weights: &'a RowWeights,
    /// Column transform of the search coordinates (`None`: the materials themselves).
    transform: Option<DMatrix<f64>>,
    rows: Vec<usize>,
    chosen: Vec<bool>,
    /// Selected rows in search coordinates (`n × N`).
    x: DMatrix<f64>,
    /// `XᵀX` (N × N) when `n ≥ N`, else `XXᵀ` (n × n).
    g: DMatrix<f64>,
    tall: bool,
    ratio: f64,
    accepted: usize,
}

/// A candidate row: uniform, or by leverage when a sampler is given.
fn draw(candidates: &[usize], sampler: Option<&WeightedIndex<f64>>, rng: &mut ChaCha8Rng) -> usize {
    match sampler {
        Some(s) => candidates[s.sample(rng)],
        None => candidates[rng.gen_range(0..candidates.len())],
    }
}

impl<'a> SearchState<'a> {
    fn new(
        training: &'a TrainingSet,
        weights: &'a RowWeights,
        transform: Option<DMatrix<f64>>,
        candidates: &[usize],
        sampler: Option<&WeightedIndex<f64>>,
        n: usize,
        rng: &mut ChaCha8Rng,
    ) -> Self {
        let d = training.dim();
        let mut chosen = vec![false; d];
        let mut rows = Vec::with_capacity(n);
        // Leverage sampling may run out of distinct heavy rows; fall back to uniform then.
        let mut tries = 0usize;
        while rows.len() < n {
            let uniform = tries > 50 * n;
            let r = draw(candidates, if uniform { None } else { sampler }, rng);
            tries += 1;
            if !chosen[r] {
                chosen[r] = true;
                rows.push(r);
            }
        }
        let mut x = weighted_row_matrix(training, &rows, weights);
        if let Some(w) = &transform {
            x = &x * w;
        }
        let tall = n >= training.len();
        let g = if tall {
            x.transpose() * &x
        } else {
            &x * x.transpose()
        };
        let ratio = gram_ratio(g.clone());
        SearchState {
            training,
            weights,
            transform,
            rows,
            chosen,
            x,
            g,
            tall,
            ratio,
            accepted: 0,
        }
    }

    /// Row `r` in search coordinates.
    fn row_vec(&self, r: usize) -> DVector<f64> {
        let d = self.training.dim();
        let w = self.weights.get(r);
        let y = DVector::from_fn(self.training.len(), |m, _| {
            f64::from(self.training.values[m * d + r]) * w
        });
        match &self.transform {
            Some(t) => t.tr_mul(&y),
            None => y,
        }
    }

    /// Tries replacing selected row number `pos` by row `cand`; keeps it if the ratio drops.
    fn try_swap(&mut self, pos: usize, cand: usize) {
        let new_row = self.row_vec(cand);
        let trial = if self.tall {
            let old_row = self.x.row(pos).transpose();
            &self.g - &old_row * old_row.transpose() + &new_row * new_row.transpose()
        } else {
            let mut t = self.g.clone();
            let dots = &self.x * &new_row;
            for i in 0..self.rows.len() {
                t[(pos, i)] = dots[i];
                t[(i, pos)] = dots[i];
            }
            t[(pos, pos)] = new_row.norm_squared();
            t
        };
        let r = gram_ratio(trial.clone());
        if r < self.ratio {
            self.ratio = r;
            self.g = trial;
            self.chosen[self.rows[pos]] = false;
            self.chosen[cand] = true;
            self.rows[pos] = cand;
            self.x.set_row(pos, &new_row.transpose());
            self.accepted += 1;
        }
    }

    /// The thesis's search: a random selected row against a drawn unselected one.
    fn search(
        &mut self,
        candidates: &[usize],
        sampler: Option<&WeightedIndex<f64>>,
        proposals: usize,
        rng: &mut ChaCha8Rng,
    ) {
        let n = self.rows.len();
        for _ in 0..proposals {
            let pos = rng.gen_range(0..n);
            let mut cand = draw(candidates, sampler, rng);
            let mut tries = 0;
            while self.chosen[cand] {
                tries += 1;
                let uniform = tries > 1000;
                cand = draw(candidates, if uniform { None } else { sampler }, rng);
            }
            self.try_swap(pos, cand);
        }
    }
}

/// Coefficients `c = X⁺ b` of the linear combination from values `b` at `rows`.
pub fn fit_coefficients(training: &TrainingSet, rows: &[usize], b: &[f64]) -> Result<Vec<f64>> {
    fit_coefficients_weighted(training, rows, b, &RowWeights::Unit)
}

/// Coefficients of the linear combination from values `b` at `rows`, by the pseudo-inverse of
/// the equations scaled by `weights`.
pub fn fit_coefficients_weighted(
    training: &TrainingSet,
    rows: &[usize],
    b: &[f64],
    weights: &RowWeights,
) -> Result<Vec<f64>> {
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
    weights.check(training.dim())?;
    let x = weighted_row_matrix(training, rows, weights);
    let bw = DVector::from_iterator(
        rows.len(),
        rows.iter().zip(b).map(|(&r, &v)| v * weights.get(r)),
    );
    let svd = x.svd(true, true);
    let smax = svd.singular_values.max();
    let eps = smax * 1e-10 * (rows.len().max(training.len()) as f64);
    let c = svd
        .solve(&bw, eps)
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

#[cfg(test)]
mod tests {
    use super::*;
    use crate::grid::SampleGrid;

    /// A corpus of `nm` materials with seeded random values spanning several decades.
    fn random_corpus(nm: usize) -> TrainingSet {
        let grid = SampleGrid::new(9, 9, 18).expect("grid");
        let mut t = TrainingSet::empty(grid);
        let mut rng = ChaCha8Rng::seed_from_u64(11);
        for m in 0..nm {
            let v: Vec<f32> = (0..t.dim())
                .map(|_| 10f32.powf(rng.gen_range(-3.0..2.0)))
                .collect();
            t.push(format!("m{m}"), &v).expect("push");
        }
        t
    }

    #[test]
    fn whitening_makes_the_corpus_gram_the_identity_and_leverages_sum_to_the_rank() {
        let t = random_corpus(7);
        let candidates: Vec<usize> = measurable_rows(&t.grid)
            .iter()
            .enumerate()
            .filter_map(|(r, &ok)| ok.then_some(r))
            .collect();
        for weights in [RowWeights::Unit, RowWeights::relative(&t)] {
            let w = whitening(&t, &weights, &candidates);
            let x = weighted_row_matrix(&t, &candidates, &weights) * &w;
            let g = x.transpose() * &x;
            let err = (g - DMatrix::<f64>::identity(7, 7)).abs().max();
            assert!(err < 1e-9, "{err}");
            let lev = leverages(&t, &weights, &candidates, &w);
            let sum: f64 = lev.iter().sum();
            assert!((sum - 7.0).abs() < 1e-9, "{sum}");
            assert!(lev.iter().all(|&l| (0.0..=1.0 + 1e-12).contains(&l)));
        }
    }
}
