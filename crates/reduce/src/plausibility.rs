//! Plausibility of synthesised BRDFs along long moves (seed §4.3–4.4, Fig. 4-7): the same
//! extrapolating move in the linear PCA space and in the chart.

use nalgebra::DVector;
use rayon::prelude::*;

use crate::charting::Chart;
use crate::corpus::{Corpus, LOG_FLOOR};
use crate::error::{ReduceError, Result};
use crate::model::Model;

/// Log-space margin beyond the corpus's per-bin range that still counts as "inside".
pub const RANGE_MARGIN: f32 = 0.5;

/// How implausible one synthesised log-space BRDF vector is.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Plausibility {
    /// Fraction of values that are clearly negative BRDF values: `y < ln(floor) − RANGE_MARGIN`,
    /// i.e. `f < −0.39 · floor` (values just under the floor are reconstruction noise of dark
    /// bins, which the linear model also produces for corpus members).
    pub negative_fraction: f64,
    /// Fraction of values outside the corpus's per-bin `[min, max]` by more than
    /// [`RANGE_MARGIN`] (natural-log units).
    pub outside_corpus_range: f64,
    /// Euclidean distance (PCA coordinates) from the starting material.
    pub distance: f64,
}

/// One step of a long-move comparison.
#[derive(Debug, Clone, PartialEq)]
pub struct MoveRow {
    /// Starting material.
    pub from: String,
    /// Material defining the direction.
    pub to: String,
    /// Step: 0 = `from`, 1 = `to`, > 1 extrapolates.
    pub t: f64,
    /// Straight line in the linear PCA space.
    pub linear: Plausibility,
    /// Straight line in the chart's embedding space, back-projected.
    pub chart: Plausibility,
}

/// Per-bin `[min, max]` of the corpus's log vectors.
pub fn corpus_range(corpus: &Corpus) -> (Vec<f32>, Vec<f32>) {
    let dim = corpus.dim();
    let mut lo = vec![f32::INFINITY; dim];
    let mut hi = vec![f32::NEG_INFINITY; dim];
    lo.par_chunks_mut(4096)
        .zip(hi.par_chunks_mut(4096))
        .enumerate()
        .for_each(|(b, (l, h))| {
            let d0 = b * 4096;
            for i in 0..corpus.len() {
                for (j, &v) in corpus.row(i)[d0..d0 + l.len()].iter().enumerate() {
                    l[j] = l[j].min(v);
                    h[j] = h[j].max(v);
                }
            }
        });
    (lo, hi)
}

/// Plausibility of a log-space vector.
pub fn assess(y: &[f32], range: &(Vec<f32>, Vec<f32>), distance: f64) -> Plausibility {
    let floor_log = LOG_FLOOR.ln() as f32;
    let (neg, out) = y
        .par_iter()
        .zip(range.0.par_iter().zip(&range.1))
        .map(|(&v, (&l, &h))| {
            (
                (v < floor_log - RANGE_MARGIN) as usize,
                (v < l - RANGE_MARGIN || v > h + RANGE_MARGIN) as usize,
            )
        })
        .reduce(|| (0, 0), |a, b| (a.0 + b.0, a.1 + b.1));
    Plausibility {
        negative_fraction: neg as f64 / y.len() as f64,
        outside_corpus_range: out as f64 / y.len() as f64,
        distance,
    }
}

/// Moves from the most specular material of the corpus (highest peak) towards the least
/// specular and towards the median one, for `t = 0, 0.5, …, 3`: once along the straight line
/// in the first `k` PCA coordinates and once along the straight line in the chart's embedding
/// space (back-projected with eq. 2.54).
pub fn long_move_comparison(
    model: &Model,
    chart: &Chart,
    corpus: &Corpus,
    k: usize,
) -> Result<Vec<MoveRow>> {
    let kc = chart.charts.ambient_dim();
    if k > model.components() || kc > k || corpus.len() != model.names.len() {
        return Err(ReduceError::InvalidParameter(format!(
            "long move: k = {k}, chart in {kc} coordinates, {} components",
            model.components()
        )));
    }
    let range = corpus_range(corpus);
    let peaks: Vec<f32> = (0..corpus.len())
        .map(|i| {
            corpus
                .row(i)
                .par_iter()
                .copied()
                .reduce(|| f32::NEG_INFINITY, f32::max)
        })
        .collect();
    let mut order: Vec<usize> = (0..corpus.len()).collect();
    order.sort_by(|&a, &b| peaks[b].total_cmp(&peaks[a]));
    let a = order[0];
    let pairs = [(a, order[order.len() - 1]), (a, order[order.len() / 2])];
    let coords = |i: usize| -> Vec<f64> { (0..k).map(|c| model.pca.coords[(i, c)]).collect() };
    let mut rows = Vec::new();
    for (a, b) in pairs {
        let (xa, xb) = (coords(a), coords(b));
        let ea = chart.forward(&DVector::from_column_slice(&xa[..kc]))?;
        let eb = chart.forward(&DVector::from_column_slice(&xb[..kc]))?;
        for step in 0..=6 {
            let t = step as f64 * 0.5;
            let xl: Vec<f64> = xa.iter().zip(&xb).map(|(p, q)| p + t * (q - p)).collect();
            let dl = xl
                .iter()
                .zip(&xa)
                .map(|(p, q)| (p - q).powi(2))
                .sum::<f64>()
                .sqrt();
            let linear = assess(&model.pca.reconstruct(&xl)?, &range, dl);
            let e = &ea + (&eb - &ea) * t;
            let mut xc = chart.backward_vec(e.as_slice())?;
            xc.resize(k, 0.0);
            let dc = xc
                .iter()
                .zip(&xa)
                .map(|(p, q)| (p - q).powi(2))
                .sum::<f64>()
                .sqrt();
            let chartp = assess(&model.pca.reconstruct(&xc)?, &range, dc);
            rows.push(MoveRow {
                from: model.names[a].clone(),
                to: model.names[b].clone(),
                t,
                linear,
                chart: chartp,
            });
        }
    }
    Ok(rows)
}
