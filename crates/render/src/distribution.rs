//! Piecewise-constant distributions sampled by CDF inversion (thesis A.2.2, transformation method).

/// A discrete distribution over `n` cells proportional to non-negative weights, with the
/// continuous piecewise-constant density on `[0, 1)` it induces.
#[derive(Debug, Clone)]
pub struct Distribution1D {
    weights: Vec<f64>,
    cdf: Vec<f64>,
    total: f64,
}

impl Distribution1D {
    /// Builds the distribution. Negative or non-finite weights count as zero. Returns `None`
    /// when there are no cells or all weights are zero.
    pub fn new(weights: &[f64]) -> Option<Self> {
        let weights: Vec<f64> = weights
            .iter()
            .map(|&w| if w.is_finite() && w > 0.0 { w } else { 0.0 })
            .collect();
        let mut cdf = Vec::with_capacity(weights.len() + 1);
        cdf.push(0.0);
        let mut acc = 0.0;
        for w in &weights {
            acc += w;
            cdf.push(acc);
        }
        if acc.is_nan() || acc <= 0.0 || !acc.is_finite() {
            return None;
        }
        for c in cdf.iter_mut() {
            *c /= acc;
        }
        Some(Self {
            weights,
            cdf,
            total: acc,
        })
    }

    /// Number of cells.
    pub fn len(&self) -> usize {
        self.weights.len()
    }

    /// Always false (an empty distribution cannot be built).
    pub fn is_empty(&self) -> bool {
        self.weights.is_empty()
    }

    /// The normalised CDF at the cell edges: `len() + 1` values from 0 to 1.
    pub fn cdf(&self) -> &[f64] {
        &self.cdf
    }

    /// Sum of the (clamped) weights.
    pub fn total(&self) -> f64 {
        self.total
    }

    /// Probability of cell `i`.
    #[inline]
    pub fn probability(&self, i: usize) -> f64 {
        self.weights.get(i).map_or(0.0, |w| w / self.total)
    }

    /// Picks a cell for the uniform number `u ∈ [0, 1)` by binary search on the CDF; returns
    /// the cell and `u` re-scaled to `[0, 1)` within that cell (for reuse).
    pub fn sample_discrete(&self, u: f64) -> (usize, f64) {
        let n = self.weights.len();
        // first index with cdf[i+1] > u, skipping zero-weight cells
        let mut lo = 0usize;
        let mut hi = n - 1;
        while lo < hi {
            let mid = (lo + hi) / 2;
            if self.cdf[mid + 1] <= u {
                lo = mid + 1;
            } else {
                hi = mid;
            }
        }
        let mut i = lo;
        while self.weights[i] == 0.0 && i + 1 < n {
            i += 1;
        }
        while self.weights[i] == 0.0 && i > 0 {
            i -= 1;
        }
        let width = self.cdf[i + 1] - self.cdf[i];
        let rem = if width > 0.0 {
            ((u - self.cdf[i]) / width).clamp(0.0, 1.0 - f64::EPSILON)
        } else {
            0.5
        };
        (i, rem)
    }

    /// Continuous sample in `[0, 1)` with its density `n · p_i`.
    pub fn sample_continuous(&self, u: f64) -> (f64, f64, usize) {
        let (i, rem) = self.sample_discrete(u);
        let n = self.weights.len() as f64;
        let x = (i as f64 + rem) / n;
        (x, self.probability(i) * n, i)
    }

    /// Density of the continuous distribution at `x ∈ [0, 1)`.
    pub fn density(&self, x: f64) -> f64 {
        let n = self.weights.len();
        let i = ((x * n as f64) as usize).min(n - 1);
        self.probability(i) * n as f64
    }
}

/// A piecewise-constant 2D distribution on `[0, 1)²` (rows = `v`, columns = `u`): a marginal
/// over rows and a conditional over columns for each row.
#[derive(Debug, Clone)]
pub struct Distribution2D {
    width: usize,
    height: usize,
    rows: Vec<Option<Distribution1D>>,
    marginal: Distribution1D,
}

impl Distribution2D {
    /// Builds from row-major weights (`height` rows of `width`). `None` when all are zero or the
    /// dimensions do not match.
    pub fn new(weights: &[f64], width: usize, height: usize) -> Option<Self> {
        if width == 0 || height == 0 || weights.len() != width * height {
            return None;
        }
        let rows: Vec<Option<Distribution1D>> =
            weights.chunks(width).map(Distribution1D::new).collect();
        let row_totals: Vec<f64> = rows
            .iter()
            .map(|r| r.as_ref().map_or(0.0, |d| d.total()))
            .collect();
        let marginal = Distribution1D::new(&row_totals)?;
        Some(Self {
            width,
            height,
            rows,
            marginal,
        })
    }

    /// Samples `(u, v) ∈ [0, 1)²` and returns it with its density.
    pub fn sample(&self, u1: f64, u2: f64) -> ([f64; 2], f64) {
        let (v, pv, row) = self.marginal.sample_continuous(u1);
        match &self.rows[row] {
            Some(d) => {
                let (u, pu, _) = d.sample_continuous(u2);
                ([u, v], pu * pv)
            }
            None => ([u2, v], 0.0),
        }
    }

    /// Density at `(u, v)`.
    pub fn density(&self, u: f64, v: f64) -> f64 {
        let row = ((v * self.height as f64) as usize).min(self.height - 1);
        match &self.rows[row] {
            Some(d) => self.marginal.density(v) * d.density(u),
            None => 0.0,
        }
    }

    /// Grid width (columns).
    pub fn width(&self) -> usize {
        self.width
    }

    /// Grid height (rows).
    pub fn height(&self) -> usize {
        self.height
    }
}

/// Walker's alias table of a discrete distribution (Vose's construction): a cell is drawn from
/// one uniform number in constant time with two table reads, where [`Distribution1D`] searches
/// its CDF. Used where a search is costly, as in the vectorised Mitsuba plugin, which reads
/// these tables on the device.
///
/// Cell `i` is kept with probability `threshold(i)` and otherwise replaced by `alias(i)`; the
/// probability of drawing `j` is `(threshold(j) + Σ_{alias(i) = j} (1 − threshold(i))) / n`.
///
/// ```
/// use render::AliasTable;
///
/// let table = AliasTable::new(&[1.0, 0.0, 3.0]).unwrap();
/// let (cell, rest) = table.sample(0.9);
/// assert_eq!(cell, 2);
/// assert!((0.0..1.0).contains(&rest));
/// assert!((table.probability_of(2) - 0.75).abs() < 1e-6);
/// assert_eq!(table.probability_of(1), 0.0);
/// ```
#[derive(Debug, Clone)]
pub struct AliasTable {
    threshold: Vec<f32>,
    alias: Vec<u32>,
}

impl AliasTable {
    /// Builds the table. Negative or non-finite weights count as zero. Returns `None` when
    /// there are no cells, all weights are zero, or there are more than 2²⁴ cells (an alias
    /// index must be exact in `f32`, as the plugin stores it).
    pub fn new(weights: &[f64]) -> Option<Self> {
        let n = weights.len();
        if n == 0 || n > 1 << 24 {
            return None;
        }
        let clean = |w: f64| if w.is_finite() && w > 0.0 { w } else { 0.0 };
        let total: f64 = weights.iter().map(|&w| clean(w)).sum();
        if !(total.is_finite() && total > 0.0) {
            return None;
        }
        // scaled so that the mean is one
        let mut scaled: Vec<f64> = weights
            .iter()
            .map(|&w| clean(w) * n as f64 / total)
            .collect();
        let mut threshold = vec![1f32; n];
        let mut alias: Vec<u32> = (0..n as u32).collect();
        let (mut small, mut large): (Vec<usize>, Vec<usize>) =
            (0..n).partition(|&i| scaled[i] < 1.0);
        while let (Some(&s), Some(&l)) = (small.last(), large.last()) {
            small.pop();
            threshold[s] = scaled[s] as f32;
            alias[s] = l as u32;
            scaled[l] -= 1.0 - scaled[s];
            if scaled[l] < 1.0 {
                large.pop();
                small.push(l);
            }
        }
        // what remains on either list holds (up to rounding) exactly one cell's worth
        for i in small.into_iter().chain(large) {
            threshold[i] = 1.0;
            alias[i] = i as u32;
        }
        Some(Self { threshold, alias })
    }

    /// Number of cells.
    pub fn len(&self) -> usize {
        self.threshold.len()
    }

    /// Always false (an empty table cannot be built).
    pub fn is_empty(&self) -> bool {
        self.threshold.is_empty()
    }

    /// The probability of keeping each cell.
    pub fn threshold(&self) -> &[f32] {
        &self.threshold
    }

    /// The cell that replaces each cell when it is not kept.
    pub fn alias(&self) -> &[u32] {
        &self.alias
    }

    /// Draws a cell for the uniform number `u ∈ [0, 1)`; returns it with a second uniform
    /// number in `[0, 1)`, independent of the choice (the rest of `u`, re-scaled).
    pub fn sample(&self, u: f64) -> (usize, f64) {
        let n = self.threshold.len();
        let x = u.clamp(0.0, 1.0) * n as f64;
        let i = (x as usize).min(n - 1);
        let f = (x - i as f64).clamp(0.0, 1.0);
        let t = self.threshold[i] as f64;
        if f < t {
            (i, (f / t).min(1.0 - f64::EPSILON))
        } else {
            let rest = ((f - t) / (1.0 - t)).clamp(0.0, 1.0 - f64::EPSILON);
            (self.alias[i] as usize, rest)
        }
    }

    /// The probability with which [`Self::sample`] draws cell `j` (summed over the table).
    pub fn probability_of(&self, j: usize) -> f64 {
        let n = self.threshold.len();
        let mut p = if j < n { self.threshold[j] as f64 } else { 0.0 };
        for (i, (&t, &a)) in self.threshold.iter().zip(&self.alias).enumerate() {
            if a as usize == j && i != j {
                p += 1.0 - t as f64;
            }
        }
        p / n as f64
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn discrete_sampling_matches_weights() {
        let d = Distribution1D::new(&[1.0, 0.0, 3.0, 0.0]).unwrap();
        let mut counts = [0usize; 4];
        let n = 40_000;
        for i in 0..n {
            let u = (i as f64 + 0.5) / n as f64;
            counts[d.sample_discrete(u).0] += 1;
        }
        assert_eq!(counts[1], 0);
        assert_eq!(counts[3], 0);
        assert!((counts[0] as f64 / n as f64 - 0.25).abs() < 1e-3);
        assert!((d.density(0.6) - 3.0).abs() < 1e-12);
        assert!(Distribution1D::new(&[0.0, f64::NAN]).is_none());
    }

    #[test]
    fn two_d_density_integrates_to_one() {
        let w: Vec<f64> = (0..12).map(|i| (i % 5) as f64).collect();
        let d = Distribution2D::new(&w, 4, 3).unwrap();
        let mut s = 0.0;
        for j in 0..3 {
            for i in 0..4 {
                s += d.density((i as f64 + 0.5) / 4.0, (j as f64 + 0.5) / 3.0) / 12.0;
            }
        }
        assert!((s - 1.0).abs() < 1e-12);
        let ([u, v], p) = d.sample(0.3, 0.7);
        assert!((d.density(u, v) - p).abs() < 1e-9);
    }

    #[test]
    fn an_alias_table_draws_each_cell_with_its_weight() {
        use rand::{Rng, SeedableRng};
        let mut rng = rand::rngs::StdRng::seed_from_u64(11);
        for n in [1usize, 2, 7, 90, 180, 1000] {
            let weights: Vec<f64> = (0..n)
                .map(|i| {
                    if i % 5 == 3 {
                        0.0
                    } else {
                        rng.gen::<f64>().powi(4) * 10.0
                    }
                })
                .collect();
            let weights = if weights.iter().all(|&w| w == 0.0) {
                vec![1.0; n]
            } else {
                weights
            };
            let total: f64 = weights.iter().sum();
            let table = AliasTable::new(&weights).unwrap();
            for (j, w) in weights.iter().enumerate() {
                let p = table.probability_of(j);
                assert!(
                    (p - w / total).abs() <= 1e-6 * (1.0 + w / total),
                    "n {n} cell {j}: {p} vs {}",
                    w / total
                );
            }
            // every cell drawn is one with weight, and the remainder is uniform: the mean of
            // the remainders over a stratified sweep is one half
            let m = 20_000;
            let mut rest_sum = 0.0;
            for s in 0..m {
                let (cell, rest) = table.sample((s as f64 + 0.5) / m as f64);
                assert!(weights[cell] > 0.0, "n {n}: drew the empty cell {cell}");
                assert!((0.0..1.0).contains(&rest));
                rest_sum += rest;
            }
            assert!(
                (rest_sum / m as f64 - 0.5).abs() < 0.02,
                "n {n}: {}",
                rest_sum / m as f64
            );
        }
        assert!(AliasTable::new(&[]).is_none());
        assert!(AliasTable::new(&[0.0, f64::NAN, -1.0]).is_none());
    }
}
