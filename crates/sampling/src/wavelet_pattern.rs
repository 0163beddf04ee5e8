//! Wavelet sampling pattern (thesis §6.3, eqs. 6.6–6.7) on a sample grid.

use std::collections::HashMap;

use rand::seq::SliceRandom;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rayon::prelude::*;
use wavelet::CoefficientAddress;
use wavelet::{CommonBasis, CommonBasisBuilder, Cube, Layout, Wavelet};

use crate::error::{Result, SamplingError};
use crate::grid::{GridTable, SampleGrid};
use crate::training::{from_log_clamped, measurable, to_log, TrainingSet};

fn wavelet_err(e: wavelet::WaveletError) -> SamplingError {
    SamplingError::InvalidParameter(format!("wavelet: {e}"))
}

/// Materials whose channels are thresholded together while building the basis.
const BUILD_BATCH: usize = 4;

/// Random draws inside a support before [`WaveletPatternModel::select_points`] falls back to
/// enumerating the support.
const POINT_DRAWS: usize = 64;

/// The coarse grid of block averages that estimates the lowest wavelet levels (§6.3: "I
/// collapse the sparse … BRDF values from a 256 × 256 × 256 grid to a 16 × 16 × 16 grid by
/// averaging the values … The coefficients of the low resolution grid approximate well the low
/// level coefficients of the high resolution grid").
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct CoarseGrid {
    /// Side of the coarse grid (a power of two, at most the cube side).
    pub side: usize,
    /// Levels `0..levels` of the CWB are taken from the coarse grid (at most log2 `side`).
    pub levels: u32,
}

impl CoarseGrid {
    /// The thesis's choice: a 16³ grid gives levels 0, 1 and 2.
    pub const SEED: CoarseGrid = CoarseGrid {
        side: 16,
        levels: 3,
    };

    /// The thesis's geometry for a cube of side `side`: blocks of 16 cells per axis (at least 2
    /// blocks), levels `0..min(3, log2 blocks)`. For the 256³ cube this is [`CoarseGrid::SEED`].
    pub fn for_cube(side: usize) -> CoarseGrid {
        let blocks = (side / 16).max(2);
        CoarseGrid {
            side: blocks,
            levels: blocks.trailing_zeros().min(3),
        }
    }
}

/// A Common Wavelet Basis on a grid, with the corpus-mean coefficients: the wavelet sampling
/// pattern of thesis §6.3 (eqs. 6.6–6.7).
///
/// The grid's θh × θd × φd table is zero-padded into a cube of side `2^L` (the `wavelet`
/// crate's [`Layout`]; 256 on the full MERL grid). The Common Wavelet Basis (CWB) is the
/// union, over every training material and channel (in log space, `ln(f + 10⁻³)`), of the
/// Haar coefficients needed for a relative error ≤ `target`. Sample points: for each CWB
/// function in coarse-to-fine order, one not yet chosen, measurable grid point inside its
/// support (seeded, uniform among the open points), so every function is touched by at least
/// one equation; all three channels are measured there. The coefficients solve the sparse
/// least-squares problem `H c = g` (6.7) per channel by CGLS, written relative to the CWB
/// coefficients of the corpus mean, with a small damping so that directions the samples do
/// not determine stay at the mean. Optionally ([`CoarseGrid`]) the lowest levels are instead
/// estimated from block averages of the samples on a coarse grid, as the thesis does with a
/// 16³ grid; only the finer coefficients are then solved for.
///
/// # Examples
///
/// ```
/// use sampling::WaveletPatternModel;
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
/// let model = WaveletPatternModel::build(&set, 0.03).unwrap();
/// assert!(!model.is_empty() && model.len() < 3 * grid.len());
/// // One point per basis function, about twice over, all distinct.
/// let points = model.select_points(2.0, 7).unwrap();
/// let mut distinct = points.clone();
/// distinct.sort_unstable();
/// distinct.dedup();
/// assert_eq!(distinct.len(), points.len());
/// // Every point touches at least one basis function.
/// assert!(points.iter().all(|&p| !model.row(p).is_empty()));
/// // Measure a training material there (three channels per point) and solve for the rest.
/// let samples: Vec<(usize, usize, f64)> = points
///     .iter()
///     .flat_map(|&p| (0..3).map(move |ch| (p, ch)))
///     .map(|(p, ch)| (p, ch, target.get(ch, p)))
///     .collect();
/// let table = model.reconstruct(&samples, 200, 1e-6, None).unwrap();
/// let err = metrics::log_rms_relative(&target, &table).unwrap();
/// assert!(err < 0.03, "relative log RMS error {err}");
/// ```
#[derive(Debug, Clone)]
pub struct WaveletPatternModel {
    /// The grid.
    pub grid: SampleGrid,
    /// The Common Wavelet Basis.
    pub basis: CommonBasis,
    /// CWB coefficients of the corpus mean (log space), per channel.
    pub mean_coefficients: [Vec<f64>; 3],
    column: HashMap<u32, usize>,
}

/// The Haar layout of a grid: extent = grid shape, side = next power of two.
pub fn layout_of(grid: &SampleGrid) -> Layout {
    let (a, b, c) = grid.shape();
    Layout {
        side: a.max(b).max(c).next_power_of_two().max(2),
        extent: [a, b, c],
        wavelet: Wavelet::Haar,
    }
}

impl WaveletPatternModel {
    /// Builds the CWB of the training set at relative-error target `target` (seed: 0.03).
    pub fn build(training: &TrainingSet, target: f64) -> Result<Self> {
        let grid = training.grid;
        let layout = layout_of(&grid);
        let g = grid.len();
        let n = training.len();
        if n == 0 {
            return Err(SamplingError::InvalidParameter("empty training set".into()));
        }
        // Streamed a few materials at a time: no log copy of the whole corpus.
        let mut builder = CommonBasisBuilder::new(layout, target).map_err(wavelet_err)?;
        let mut mean_logs = vec![vec![0f64; g]; 3];
        for first in (0..n).step_by(BUILD_BATCH) {
            let last = (first + BUILD_BATCH).min(n);
            let comps: Vec<Vec<f32>> = (first..last)
                .flat_map(|m| (0..3).map(move |ch| (m, ch)))
                .map(|(m, ch)| {
                    training.material(m)[ch * g..(ch + 1) * g]
                        .iter()
                        .map(|&v| to_log(f64::from(v)) as f32)
                        .collect()
                })
                .collect();
            for (i, c) in comps.iter().enumerate() {
                for (s, &v) in mean_logs[i % 3].iter_mut().zip(c) {
                    *s += f64::from(v);
                }
            }
            let refs: Vec<&[f32]> = comps.iter().map(|c| c.as_slice()).collect();
            builder.add_many(&refs).map_err(wavelet_err)?;
        }
        let basis = builder.finish();
        let mut mean_coefficients: [Vec<f64>; 3] = Default::default();
        for ch in 0..3 {
            let mean: Vec<f32> = mean_logs[ch]
                .iter()
                .map(|s| (s / n as f64) as f32)
                .collect();
            mean_coefficients[ch] = basis
                .coefficients(&mean)
                .map_err(wavelet_err)?
                .into_iter()
                .map(f64::from)
                .collect();
        }
        Ok(Self::assemble(grid, basis, mean_coefficients))
    }

    /// The model of a basis and its mean coefficients, with the index → column map.
    fn assemble(grid: SampleGrid, basis: CommonBasis, mean_coefficients: [Vec<f64>; 3]) -> Self {
        let column = basis
            .indices()
            .iter()
            .enumerate()
            .map(|(c, &i)| (i, c))
            .collect();
        WaveletPatternModel {
            grid,
            basis,
            mean_coefficients,
            column,
        }
    }

    /// Rebuilds a model from its parts (used by the model file).
    pub fn from_parts(
        grid: SampleGrid,
        indices: Vec<u32>,
        mean_coefficients: [Vec<f64>; 3],
    ) -> Result<Self> {
        let basis = CommonBasis::from_indices(layout_of(&grid), indices).map_err(wavelet_err)?;
        if mean_coefficients.iter().any(|m| m.len() != basis.len()) {
            return Err(SamplingError::Dimension(
                "mean coefficients do not match the basis".into(),
            ));
        }
        Ok(Self::assemble(grid, basis, mean_coefficients))
    }

    /// Number of CWB functions.
    pub fn len(&self) -> usize {
        self.basis.len()
    }

    /// Whether the basis is empty.
    pub fn is_empty(&self) -> bool {
        self.basis.is_empty()
    }

    fn side(&self) -> usize {
        self.basis.layout().side
    }

    /// Sparse row of `H` at grid point `p`: (column, Haar value) of every CWB function whose
    /// support contains the point.
    pub fn row(&self, p: usize) -> Vec<(usize, f64)> {
        let side = self.side();
        let levels = side.trailing_zeros();
        let (a, b, c) = self.grid.coords(p);
        let cell = [a, b, c];
        let mut out = Vec::new();
        for level in 0..levels {
            let w = side >> level;
            let offset = cell.map(|x| (x / w) as u32);
            let kinds: &[u8] = if level == 0 {
                &[0, 1, 2, 3, 4, 5, 6, 7]
            } else {
                &[1, 2, 3, 4, 5, 6, 7]
            };
            for &kind in kinds {
                let addr = CoefficientAddress {
                    level,
                    kind,
                    offset,
                };
                let [x, y, z] = addr.to_coords();
                let flat = ((x * side + y) * side + z) as u32;
                if let Some(&col) = self.column.get(&flat) {
                    out.push((col, addr.haar_value(side, cell)));
                }
            }
        }
        out
    }

    /// The sample points: one per CWB function (coarse to fine), about `oversample ×` the
    /// basis size in total, distinct and measurable.
    pub fn select_points(&self, oversample: f64, seed: u64) -> Result<Vec<usize>> {
        if !(oversample.is_finite() && oversample > 0.0) {
            return Err(SamplingError::InvalidParameter(format!(
                "oversample {oversample}"
            )));
        }
        let side = self.side();
        let (na, nb, nc) = self.grid.shape();
        let mut order: Vec<usize> = (0..self.len()).collect();
        order.sort_by_key(|&i| self.basis.address(i).level);
        let target = ((self.len() as f64) * oversample).round() as usize;
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        let open: Vec<bool> = (0..self.grid.len())
            .into_par_iter()
            .map(|p| measurable(&self.grid, p))
            .collect();
        // `open[p]`: measurable and not chosen yet.
        let mut open = open;
        let mut points = Vec::with_capacity(target);
        'outer: while points.len() < target {
            let before = points.len();
            for &i in &order {
                if points.len() >= target {
                    break 'outer;
                }
                let s = self.basis.address(i).support(side);
                let (a0, a1) = (s[0].start, s[0].end.min(na));
                let (b0, b1) = (s[1].start, s[1].end.min(nb));
                let (c0, c1) = (s[2].start, s[2].end.min(nc));
                if a0 >= a1 || b0 >= b1 || c0 >= c1 {
                    continue;
                }
                // Uniform over the open points of the support: rejection sampling first,
                // enumeration when the support is (nearly) exhausted.
                let mut pick = None;
                for _ in 0..POINT_DRAWS {
                    let p = self.grid.index(
                        rng.gen_range(a0..a1),
                        rng.gen_range(b0..b1),
                        rng.gen_range(c0..c1),
                    );
                    if open[p] {
                        pick = Some(p);
                        break;
                    }
                }
                if pick.is_none() {
                    let mut cands = Vec::new();
                    for a in a0..a1 {
                        for b in b0..b1 {
                            for c in c0..c1 {
                                let p = self.grid.index(a, b, c);
                                if open[p] {
                                    cands.push(p);
                                }
                            }
                        }
                    }
                    pick = cands.choose(&mut rng).copied();
                }
                if let Some(p) = pick {
                    open[p] = false;
                    points.push(p);
                }
            }
            if points.len() == before {
                break;
            }
        }
        points.sort_unstable();
        Ok(points)
    }

    /// Value at grid point `p` of the function whose CWB coefficients are `coefficients`.
    fn eval_row(&self, row: &[(usize, f64)], coefficients: &[f64]) -> f64 {
        row.iter().map(|&(c, h)| h * coefficients[c]).sum()
    }

    /// Estimates of the Haar coefficients of levels `0..coarse.levels` from block averages of
    /// log-space samples of one channel (§6.3), as `(CWB column, coefficient)` pairs for the
    /// coarse coefficients that are in the CWB.
    ///
    /// The cube is cut into `coarse.side³` blocks of `w³` cells. In every block the mean of
    /// the residuals `y − m(p)` of its samples (`m` = the corpus-mean function on the CWB)
    /// is added to `m` on every table cell of the block; padding cells are 0. The block means
    /// of that function form the coarse grid; its full Haar transform, times `w^{3/2}`,
    /// gives the coefficients of the fine cube at the same positions. Blocks without samples
    /// keep the mean function. With every table cell sampled the estimate is exact.
    pub fn coarse_coefficients(
        &self,
        channel: usize,
        samples: &[(usize, f64)],
        coarse: CoarseGrid,
    ) -> Result<Vec<(usize, f64)>> {
        let side = self.side();
        if channel > 2 {
            return Err(SamplingError::InvalidParameter(format!(
                "channel {channel}"
            )));
        }
        if !coarse.side.is_power_of_two()
            || coarse.side < 2
            || coarse.side > side
            || coarse.levels > coarse.side.trailing_zeros()
        {
            return Err(SamplingError::InvalidParameter(format!(
                "coarse grid {coarse:?} for a cube of side {side}"
            )));
        }
        let w = side / coarse.side;
        let cs = coarse.side;
        let block = |p: usize| {
            let (a, b, c) = self.grid.coords(p);
            ((a / w) * cs + b / w) * cs + c / w
        };
        let g = self.grid.len();
        let mean_coefficients = &self.mean_coefficients[channel];
        // The mean function on the table, and its sum per block.
        let mean_f32: Vec<f32> = mean_coefficients.iter().map(|&c| c as f32).collect();
        let mean_table = self.basis.reconstruct(&mean_f32).map_err(wavelet_err)?;
        let mut sum = vec![0f64; cs * cs * cs];
        let mut cells = vec![0usize; cs * cs * cs];
        for (p, &m) in mean_table.iter().enumerate() {
            let b = block(p);
            sum[b] += f64::from(m);
            cells[b] += 1;
        }
        let mut residual = vec![0f64; cs * cs * cs];
        let mut count = vec![0usize; cs * cs * cs];
        for &(p, y) in samples {
            if p >= g {
                return Err(SamplingError::Dimension(format!("grid point {p}")));
            }
            if !y.is_finite() {
                return Err(SamplingError::NonFinite("sample".into()));
            }
            let b = block(p);
            residual[b] += y - f64::from(mean_table[p]);
            count[b] += 1;
        }
        let volume = (w * w * w) as f64;
        let means: Vec<f32> = (0..cs * cs * cs)
            .map(|b| {
                let r = if count[b] > 0 {
                    residual[b] / count[b] as f64
                } else {
                    0.0
                };
                ((sum[b] + cells[b] as f64 * r) / volume) as f32
            })
            .collect();
        let mut cube = Cube::from_vec(cs, means).map_err(wavelet_err)?;
        wavelet::forward_full(&mut cube, Wavelet::Haar).map_err(wavelet_err)?;
        let scale = wavelet::coarse_to_fine_scale(side, cs);
        let lim = 1usize << coarse.levels;
        let mut out = Vec::new();
        for x in 0..lim {
            for y in 0..lim {
                for z in 0..lim {
                    let flat = ((x * side + y) * side + z) as u32;
                    if let Some(&col) = self.column.get(&flat) {
                        let v = f64::from(cube.data()[(x * cs + y) * cs + z]) * scale;
                        out.push((col, v));
                    }
                }
            }
        }
        Ok(out)
    }

    /// Reconstruction from `(grid point, channel, value)` samples: the sparse solve of (6.7),
    /// with the lowest levels taken from the coarse grid of block averages when `coarse` is
    /// given (§6.3).
    pub fn reconstruct(
        &self,
        samples: &[(usize, usize, f64)],
        iterations: usize,
        damping: f64,
        coarse: Option<CoarseGrid>,
    ) -> Result<GridTable> {
        let g = self.grid.len();
        let mut values = vec![0.0; 3 * g];
        let chans: Vec<Result<Vec<f32>>> = (0..3)
            .into_par_iter()
            .map(|ch| {
                let logs: Vec<(usize, f64)> = samples
                    .iter()
                    .filter(|s| s.1 == ch)
                    .map(|&(p, _, v)| {
                        if p >= g {
                            return Err(SamplingError::Dimension(format!("grid point {p}")));
                        }
                        if !v.is_finite() {
                            return Err(SamplingError::NonFinite("sample".into()));
                        }
                        Ok((p, to_log(v)))
                    })
                    .collect::<Result<_>>()?;
                let mean = &self.mean_coefficients[ch];
                // Offsets from the mean of the coefficients fixed by the coarse grid.
                let mut fixed: Vec<Option<f64>> = vec![None; self.len()];
                if let Some(cg) = coarse {
                    for (col, v) in self.coarse_coefficients(ch, &logs, cg)? {
                        fixed[col] = Some(v - mean[col]);
                    }
                }
                let rows: Vec<(Vec<(usize, f64)>, f64)> = logs
                    .iter()
                    .map(|&(p, y)| {
                        let row = self.row(p);
                        let mut rhs = y - self.eval_row(&row, mean);
                        let mut free = Vec::with_capacity(row.len());
                        for (c, h) in row {
                            match fixed[c] {
                                Some(d) => rhs -= h * d,
                                None => free.push((c, h)),
                            }
                        }
                        (free, rhs)
                    })
                    .collect();
                let delta = cgls(&rows, self.len(), iterations, damping);
                let coeffs: Vec<f32> = delta
                    .iter()
                    .zip(mean)
                    .zip(&fixed)
                    .map(|((d, m), f)| (m + f.unwrap_or(*d)) as f32)
                    .collect();
                self.basis.reconstruct(&coeffs).map_err(wavelet_err)
            })
            .collect();
        for (ch, r) in chans.into_iter().enumerate() {
            for (o, y) in values[ch * g..(ch + 1) * g].iter_mut().zip(r?) {
                *o = from_log_clamped(y as f64);
            }
        }
        GridTable::new(self.grid, values)
    }
}

/// CGLS for `min ‖A x − b‖² + damping ‖x‖²` with sparse rows `(row, b_i)` of `(column,
/// value)` entries. Entries with a column `≥ n` are ignored. The matrix is stored once by rows
/// and once by columns, so that both `A x` and `Aᵀ y` are parallel gathers.
pub fn cgls(
    rows: &[(Vec<(usize, f64)>, f64)],
    n: usize,
    iterations: usize,
    damping: f64,
) -> Vec<f64> {
    let m = rows.len();
    // By rows (CSR).
    let mut row_ptr = Vec::with_capacity(m + 1);
    let mut cols: Vec<u32> = Vec::new();
    let mut vals: Vec<f64> = Vec::new();
    row_ptr.push(0usize);
    let mut col_count = vec![0usize; n + 1];
    for (r, _) in rows {
        for &(c, h) in r {
            if c < n {
                cols.push(c as u32);
                vals.push(h);
                col_count[c + 1] += 1;
            }
        }
        row_ptr.push(cols.len());
    }
    // By columns (CSC), rows increasing within a column.
    for j in 0..n {
        col_count[j + 1] += col_count[j];
    }
    let col_ptr = col_count;
    let mut fill = col_ptr.clone();
    let mut t_rows = vec![0u32; cols.len()];
    let mut t_vals = vec![0f64; cols.len()];
    for i in 0..m {
        for e in row_ptr[i]..row_ptr[i + 1] {
            let c = cols[e] as usize;
            t_rows[fill[c]] = i as u32;
            t_vals[fill[c]] = vals[e];
            fill[c] += 1;
        }
    }
    let apply = |x: &[f64]| -> Vec<f64> {
        (0..m)
            .into_par_iter()
            .with_min_len(4096)
            .map(|i| {
                (row_ptr[i]..row_ptr[i + 1])
                    .map(|e| vals[e] * x[cols[e] as usize])
                    .sum()
            })
            .collect()
    };
    let apply_t = |y: &[f64]| -> Vec<f64> {
        (0..n)
            .into_par_iter()
            .with_min_len(4096)
            .map(|j| {
                (col_ptr[j]..col_ptr[j + 1])
                    .map(|e| t_vals[e] * y[t_rows[e] as usize])
                    .sum()
            })
            .collect()
    };
    let mut x = vec![0.0; n];
    let mut r: Vec<f64> = rows.iter().map(|(_, b)| *b).collect();
    let mut s = apply_t(&r);
    let mut p = s.clone();
    let mut gamma: f64 = s.iter().map(|v| v * v).sum();
    let gamma0 = gamma;
    for _ in 0..iterations {
        if gamma <= gamma0 * 1e-24 || gamma == 0.0 {
            break;
        }
        let q = apply(&p);
        let denom: f64 =
            q.iter().map(|v| v * v).sum::<f64>() + damping * p.iter().map(|v| v * v).sum::<f64>();
        if denom <= 0.0 {
            break;
        }
        let alpha = gamma / denom;
        for (xi, pi) in x.iter_mut().zip(&p) {
            *xi += alpha * pi;
        }
        for (ri, qi) in r.iter_mut().zip(&q) {
            *ri -= alpha * qi;
        }
        s = apply_t(&r);
        for (si, xi) in s.iter_mut().zip(&x) {
            *si -= damping * xi;
        }
        let g_new: f64 = s.iter().map(|v| v * v).sum();
        let beta = g_new / gamma;
        gamma = g_new;
        for (pi, si) in p.iter_mut().zip(&s) {
            *pi = si + beta * *pi;
        }
    }
    x
}
