//! Plausibility of synthesised BRDFs along long moves (thesis §4.3–4.4, Fig. 4-7).

use nalgebra::DVector;
use rand::seq::SliceRandom;
use rand::SeedableRng;
use rayon::prelude::*;

use crate::charting::Chart;
use crate::corpus::{Corpus, LOG_FLOOR};
use crate::error::{ReduceError, Result};
use crate::model::Model;

/// Log-space margin beyond the corpus's per-bin range that still counts as "inside".
pub const RANGE_MARGIN: f32 = 0.5;

/// θh bins (MERL index, `1..=HIGHLIGHT_BINS`, i.e. θh ≤ 4.4°) around the specular peak that the
/// highlight-hole test compares with the peak bin θh = 0.
pub const HIGHLIGHT_BINS: usize = 20;

/// Only θd bins below this index (θd < 60°) enter the highlight-hole test.
pub const HIGHLIGHT_MAX_THETA_D: usize = 60;

/// A (θd, φd, channel) slice has a "hole in the highlight" when its value at θh = 0 lies more
/// than this (natural-log units, i.e. a factor 2) below its maximum over θh bins
/// `1..=HIGHLIGHT_BINS`.
pub const HOLE_DEPTH: f32 = std::f32::consts::LN_2;

/// How implausible one synthesised log-space BRDF vector is: the score of every point of
/// [`long_move_comparison`], which compares the same long move away from a corpus material
/// once in the chart and once in the linear PCA space (thesis §4.3–4.4, Fig. 4-7).
///
/// Fig. 4-7 compares "moving away from a point A on the 45-dimensional linear subspace" with
/// "moving equally far away from point A on the 15-dimensional non-linear manifold". Here a move
/// starts at a corpus material `A` and heads towards another corpus material `B`:
///
/// * **chart**: the straight line `x(t) = x_A + t (x_B − x_A)` in the chart's embedding space,
///   back-projected by (2.54) into PCA coordinates;
/// * **linear**: the straight line from `A` towards `B` in the first `k` PCA coordinates,
///   stopped at the *same distance* from `A` (in PCA coordinates) as the chart point.
///
/// Each synthesised log-space vector is scored by `assess` (see [`Plausibility`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Plausibility {
    /// Fraction of values that are clearly negative BRDF values: `y < ln(floor) − RANGE_MARGIN`,
    /// i.e. `f < −0.39 · floor` (values just under the floor are reconstruction noise of dark
    /// bins, which the linear model also produces for corpus members).
    pub negative_fraction: f64,
    /// Fraction of values outside the corpus's per-bin `[min, max]` by more than
    /// [`RANGE_MARGIN`] (natural-log units).
    pub outside_corpus_range: f64,
    /// Fraction of (θd < 60°, φd, channel) slices with a hole in the specular highlight (the
    /// defect shown in the thesis's Fig. 4-7): the value at θh = 0 more than a factor 2 below the
    /// maximum over the next [`HIGHLIGHT_BINS`] θh bins.
    pub highlight_holes: f64,
    /// Distance (PCA coordinates) to the nearest corpus material, divided by the median
    /// nearest-neighbour distance within the corpus: "how far from the data density".
    pub nearest_material: f64,
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
    /// Step along the chart's straight line: 0 = `from`, 1 = `to`, > 1 extrapolates.
    pub t: f64,
    /// Straight line in the linear PCA space, at the chart point's distance from `from`.
    pub linear: Plausibility,
    /// Straight line in the chart's embedding space, back-projected.
    pub chart: Plausibility,
}

/// The corpus facts the scores are measured against.
#[derive(Debug, Clone)]
pub struct Reference {
    /// Per-bin minimum of the corpus's log vectors.
    pub lo: Vec<f32>,
    /// Per-bin maximum of the corpus's log vectors.
    pub hi: Vec<f32>,
    /// Corpus PCA coordinates (first `k`), one row per material.
    pub coords: Vec<Vec<f64>>,
    /// Median nearest-neighbour distance among `coords`.
    pub median_nn: f64,
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

fn distance(a: &[f64], b: &[f64]) -> f64 {
    a.iter()
        .zip(b)
        .map(|(p, q)| (p - q).powi(2))
        .sum::<f64>()
        .sqrt()
}

impl Reference {
    /// Builds the reference from the corpus and the first `k` PCA coordinates of the model.
    pub fn new(model: &Model, corpus: &Corpus, k: usize) -> Result<Reference> {
        if k == 0 || k > model.components() || corpus.len() != model.names.len() {
            return Err(ReduceError::InvalidParameter(format!(
                "plausibility reference: k = {k}, {} components, corpus of {} for a model of {}",
                model.components(),
                corpus.len(),
                model.names.len()
            )));
        }
        let (lo, hi) = corpus_range(corpus);
        let coords: Vec<Vec<f64>> = (0..corpus.len())
            .map(|i| (0..k).map(|c| model.pca.coords[(i, c)]).collect())
            .collect();
        let mut nn: Vec<f64> = (0..coords.len())
            .map(|i| {
                (0..coords.len())
                    .filter(|&j| j != i)
                    .map(|j| distance(&coords[i], &coords[j]))
                    .fold(f64::INFINITY, f64::min)
            })
            .collect();
        nn.sort_by(f64::total_cmp);
        let median_nn = nn[nn.len() / 2];
        Ok(Reference {
            lo,
            hi,
            coords,
            median_nn,
        })
    }

    /// Distance from `x` to the nearest corpus material over the median nearest-neighbour
    /// distance.
    pub fn nearest_material(&self, x: &[f64]) -> f64 {
        self.coords
            .iter()
            .map(|c| distance(c, x))
            .fold(f64::INFINITY, f64::min)
            / self.median_nn
    }
}

/// Fraction of highlight slices of a log-space material vector (`3 × BINS`) with a hole at
/// θh = 0 (see [`Plausibility::highlight_holes`]).
pub fn highlight_hole_fraction(y: &[f32]) -> f64 {
    use brdf::{bin_index, BINS, PHI_D_RES};
    if y.len() != 3 * BINS {
        return f64::NAN;
    }
    let slices = 3 * HIGHLIGHT_MAX_THETA_D * PHI_D_RES;
    let holes: usize = (0..slices)
        .into_par_iter()
        .filter(|&s| {
            let c = s / (HIGHLIGHT_MAX_THETA_D * PHI_D_RES);
            let td = (s / PHI_D_RES) % HIGHLIGHT_MAX_THETA_D;
            let pd = s % PHI_D_RES;
            let v = |th: usize| y[c * BINS + bin_index(th, td, pd)];
            let around = (1..=HIGHLIGHT_BINS)
                .map(v)
                .fold(f32::NEG_INFINITY, f32::max);
            v(0) < around - HOLE_DEPTH
        })
        .count();
    holes as f64 / slices as f64
}

/// Plausibility of a log-space vector `y` with PCA coordinates `x`, at `distance` from the
/// start of its move.
pub fn assess(y: &[f32], x: &[f64], reference: &Reference, distance: f64) -> Plausibility {
    let floor_log = LOG_FLOOR.ln() as f32;
    let (neg, out) = y
        .par_iter()
        .zip(reference.lo.par_iter().zip(&reference.hi))
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
        highlight_holes: highlight_hole_fraction(y),
        nearest_material: reference.nearest_material(x),
        distance,
    }
}

/// `count` distinct (start, target) pairs of corpus indices, drawn reproducibly from `seed`.
pub fn move_pairs(n: usize, count: usize, seed: u64) -> Vec<(usize, usize)> {
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed);
    let mut all: Vec<(usize, usize)> = (0..n)
        .flat_map(|a| (0..n).filter(move |&b| b != a).map(move |b| (a, b)))
        .collect();
    all.shuffle(&mut rng);
    all.truncate(count);
    all
}

/// Runs the long moves `pairs` (indices into the corpus) for the chart steps `steps`, with the
/// linear moves in the first `k` PCA coordinates (the chart must live in at most `k`).
pub fn long_move_comparison(
    model: &Model,
    chart: &Chart,
    reference: &Reference,
    pairs: &[(usize, usize)],
    steps: &[f64],
) -> Result<Vec<MoveRow>> {
    model.require_log_mapping("the plausibility of long moves")?;
    let kc = chart.charts.ambient_dim();
    let k = reference.coords.first().map_or(0, |c| c.len());
    if kc > k || k > model.components() || reference.coords.len() != model.names.len() {
        return Err(ReduceError::InvalidParameter(format!(
            "long move: chart in {kc} coordinates, linear moves in {k}, {} components",
            model.components()
        )));
    }
    if let Some(&(a, b)) = pairs
        .iter()
        .find(|&&(a, b)| a == b || a.max(b) >= model.names.len())
    {
        return Err(ReduceError::InvalidParameter(format!(
            "long move pair ({a}, {b})"
        )));
    }
    let mut rows = Vec::new();
    for &(a, b) in pairs {
        let (xa, xb) = (&reference.coords[a], &reference.coords[b]);
        let ab = distance(xa, xb);
        let ea = chart.forward(&DVector::from_column_slice(&xa[..kc]))?;
        let eb = chart.forward(&DVector::from_column_slice(&xb[..kc]))?;
        for &t in steps {
            let e = &ea + (&eb - &ea) * t;
            let mut xc = chart.backward_vec(e.as_slice())?;
            // Coordinates beyond the chart's stay those of the start.
            xc.extend_from_slice(&xa[kc..]);
            let dc = distance(&xc, xa);
            let chart_p = assess(&model.pca.reconstruct(&xc)?, &xc, reference, dc);
            let s = dc / ab;
            let xl: Vec<f64> = xa.iter().zip(xb).map(|(p, q)| p + s * (q - p)).collect();
            let linear = assess(&model.pca.reconstruct(&xl)?, &xl, reference, dc);
            rows.push(MoveRow {
                from: model.names[a].clone(),
                to: model.names[b].clone(),
                t,
                linear,
                chart: chart_p,
            });
        }
    }
    Ok(rows)
}

/// Medians over the rows of each step `t` (in order of first appearance):
/// `(t, linear, chart)` with every [`Plausibility`] field replaced by its median.
pub fn median_by_step(rows: &[MoveRow]) -> Vec<(f64, Plausibility, Plausibility)> {
    let mut steps: Vec<f64> = Vec::new();
    for r in rows {
        if !steps.contains(&r.t) {
            steps.push(r.t);
        }
    }
    let median = |mut v: Vec<f64>| {
        v.sort_by(f64::total_cmp);
        let n = v.len();
        if n % 2 == 1 {
            v[n / 2]
        } else {
            0.5 * (v[n / 2 - 1] + v[n / 2])
        }
    };
    let summarise = |ps: Vec<Plausibility>| Plausibility {
        negative_fraction: median(ps.iter().map(|p| p.negative_fraction).collect()),
        outside_corpus_range: median(ps.iter().map(|p| p.outside_corpus_range).collect()),
        highlight_holes: median(ps.iter().map(|p| p.highlight_holes).collect()),
        nearest_material: median(ps.iter().map(|p| p.nearest_material).collect()),
        distance: median(ps.iter().map(|p| p.distance).collect()),
    };
    steps
        .into_iter()
        .map(|t| {
            let sel: Vec<&MoveRow> = rows.iter().filter(|r| r.t == t).collect();
            (
                t,
                summarise(sel.iter().map(|r| r.linear).collect()),
                summarise(sel.iter().map(|r| r.chart).collect()),
            )
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use brdf::{bin_index, BINS};

    #[test]
    fn highlight_hole_is_detected_only_where_the_peak_dips() {
        // A specular lobe falling off with θh has no hole.
        let mut y = vec![0.0f32; 3 * BINS];
        for c in 0..3 {
            for th in 0..90 {
                for td in 0..90 {
                    for pd in 0..180 {
                        y[c * BINS + bin_index(th, td, pd)] = 5.0 - 0.3 * th as f32;
                    }
                }
            }
        }
        assert_eq!(highlight_hole_fraction(&y), 0.0);
        // Digging the θh = 0 bin of one channel by a factor 4 is a hole in a third of the slices.
        for td in 0..90 {
            for pd in 0..180 {
                y[bin_index(0, td, pd)] -= 4f32.ln();
            }
        }
        assert!((highlight_hole_fraction(&y) - 1.0 / 3.0).abs() < 1e-12);
        assert!(highlight_hole_fraction(&y[1..]).is_nan());
    }

    #[test]
    fn pairs_are_reproducible_and_distinct() {
        let p = move_pairs(10, 15, 4);
        assert_eq!(p, move_pairs(10, 15, 4));
        assert_eq!(p.len(), 15);
        assert!(p.iter().all(|&(a, b)| a != b && a < 10 && b < 10));
        let mut q = p.clone();
        q.sort();
        q.dedup();
        assert_eq!(q.len(), 15);
    }
}
