//! Wavelet sampling pattern (thesis §6.3, eqs. 6.6–6.7) on a [`SampleGrid`].
//!
//! The grid's θh × θd × φd table is zero-padded into a cube of side `2^L` (the `wavelet`
//! crate's [`Layout`]). The Common Wavelet Basis (CWB) is the union, over every training
//! material and channel (in log space, `ln(f + 10⁻³)`), of the Haar coefficients needed for a
//! relative error ≤ `target`. Sample points: for each CWB function in coarse-to-fine order, one
//! not yet chosen, measurable grid point inside its support (seeded random choice), so every
//! function is touched by at least one equation; all three channels are measured there. The
//! coefficients solve the sparse least-squares problem `H c = g` (6.7) per channel by CGLS,
//! written relative to the CWB coefficients of the corpus mean, with a small damping so that
//! directions the samples do not determine stay at the mean.

use std::collections::HashMap;

use rand::seq::SliceRandom;
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rayon::prelude::*;
use wavelet::basis::CoefficientAddress;
use wavelet::{CommonBasis, Layout, Wavelet};

use crate::error::{Result, SamplingError};
use crate::grid::{GridTable, SampleGrid};
use crate::training::{from_log, measurable, to_log, TrainingSet};

fn wavelet_err(e: wavelet::WaveletError) -> SamplingError {
    SamplingError::InvalidParameter(format!("wavelet: {e}"))
}

/// A Common Wavelet Basis on a grid, with the corpus-mean coefficients.
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
        let logs: Vec<f32> = training.values.iter().map(|&v| to_log(v) as f32).collect();
        let components: Vec<&[f32]> = logs.chunks(g).collect();
        let (basis, _) = CommonBasis::build(layout, &components, target).map_err(wavelet_err)?;
        let n = training.len() as f64;
        let mut mean_coefficients: [Vec<f64>; 3] = Default::default();
        for ch in 0..3 {
            let mut mean = vec![0f32; g];
            for m in 0..training.len() {
                let row = &logs[(3 * m + ch) * g..(3 * m + ch + 1) * g];
                for (s, v) in mean.iter_mut().zip(row) {
                    *s += v / n as f32;
                }
            }
            mean_coefficients[ch] = basis
                .coefficients(&mean)
                .map_err(wavelet_err)?
                .into_iter()
                .map(f64::from)
                .collect();
        }
        let column = basis
            .indices()
            .iter()
            .enumerate()
            .map(|(c, &i)| (i, c))
            .collect();
        Ok(WaveletPatternModel {
            grid,
            basis,
            mean_coefficients,
            column,
        })
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
        let column = basis
            .indices()
            .iter()
            .enumerate()
            .map(|(c, &i)| (i, c))
            .collect();
        Ok(WaveletPatternModel {
            grid,
            basis,
            mean_coefficients,
            column,
        })
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
        let mut chosen = vec![false; self.grid.len()];
        let mut points = Vec::with_capacity(target);
        'outer: while points.len() < target {
            let before = points.len();
            for &i in &order {
                if points.len() >= target {
                    break 'outer;
                }
                let s = self.basis.address(i).support(side);
                let mut cands = Vec::new();
                for a in s[0].start..s[0].end.min(na) {
                    for b in s[1].start..s[1].end.min(nb) {
                        for c in s[2].start..s[2].end.min(nc) {
                            let p = self.grid.index(a, b, c);
                            if !chosen[p] && measurable(&self.grid, p) {
                                cands.push(p);
                            }
                        }
                    }
                }
                if let Some(&p) = cands.choose(&mut rng) {
                    chosen[p] = true;
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

    /// Reconstruction from `(grid point, channel, value)` samples.
    pub fn reconstruct(
        &self,
        samples: &[(usize, usize, f64)],
        iterations: usize,
        damping: f64,
    ) -> Result<GridTable> {
        let g = self.grid.len();
        let mut values = vec![0.0; 3 * g];
        let chans: Vec<Result<Vec<f32>>> = (0..3)
            .into_par_iter()
            .map(|ch| {
                let rows: Vec<(Vec<(usize, f64)>, f64)> = samples
                    .iter()
                    .filter(|s| s.1 == ch)
                    .map(|&(p, _, v)| {
                        if p >= g {
                            return Err(SamplingError::Dimension(format!("grid point {p}")));
                        }
                        if !v.is_finite() {
                            return Err(SamplingError::NonFinite("sample".into()));
                        }
                        let row = self.row(p);
                        let prior: f64 = row
                            .iter()
                            .map(|&(c, h)| h * self.mean_coefficients[ch][c])
                            .sum();
                        Ok((row, to_log(v) - prior))
                    })
                    .collect::<Result<_>>()?;
                let delta = cgls(&rows, self.len(), iterations, damping);
                let coeffs: Vec<f32> = delta
                    .iter()
                    .zip(&self.mean_coefficients[ch])
                    .map(|(d, m)| (d + m) as f32)
                    .collect();
                self.basis.reconstruct(&coeffs).map_err(wavelet_err)
            })
            .collect();
        for (ch, r) in chans.into_iter().enumerate() {
            for (o, y) in values[ch * g..(ch + 1) * g].iter_mut().zip(r?) {
                *o = from_log(y as f64);
            }
        }
        GridTable::new(self.grid, values)
    }
}

/// CGLS for `min ‖A x − b‖² + damping ‖x‖²` with sparse rows `(row, b_i)`.
pub fn cgls(
    rows: &[(Vec<(usize, f64)>, f64)],
    n: usize,
    iterations: usize,
    damping: f64,
) -> Vec<f64> {
    let apply = |x: &[f64]| -> Vec<f64> {
        rows.iter()
            .map(|(r, _)| r.iter().map(|&(c, h)| h * x[c]).sum())
            .collect()
    };
    let apply_t = |y: &[f64]| -> Vec<f64> {
        let mut out = vec![0.0; n];
        for ((r, _), &yi) in rows.iter().zip(y) {
            for &(c, h) in r {
                out[c] += h * yi;
            }
        }
        out
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
