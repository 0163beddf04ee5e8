//! Pull-push scattered-data reconstruction (thesis §6.4, eqs. 6.8–6.12).

use crate::error::{Result, SamplingError};
use crate::grid::{GridTable, SampleGrid};
use crate::training::{from_log_clamped, to_log};

/// Where values are averaged.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Domain {
    /// BRDF values as they are (the thesis).
    Linear,
    /// `ln(f + 10⁻³)`: averages are geometric, which suits the dynamic range of BRDFs.
    #[default]
    Log,
}

#[derive(Clone)]
struct Level {
    shape: (usize, usize, usize),
    f: Vec<f64>,
    w: Vec<f64>,
}

impl Level {
    fn idx(&self, a: usize, b: usize, c: usize) -> usize {
        c + self.shape.2 * (b + self.shape.1 * a)
    }
}

const TENT_PULL: [f64; 3] = [0.25, 0.5, 0.25];
const TENT_PUSH: [f64; 3] = [0.5, 1.0, 0.5];

/// Factor applied to pulled weights (see the module documentation).
pub const WEIGHT_GAIN: f64 = 8.0;

fn pull(fine: &Level, gain: f64) -> Level {
    let (na, nb, nc) = fine.shape;
    let shape = (na.div_ceil(2), nb.div_ceil(2), nc.div_ceil(2));
    let n = shape.0 * shape.1 * shape.2;
    let mut out = Level {
        shape,
        f: vec![0.0; n],
        w: vec![0.0; n],
    };
    for i in 0..shape.0 {
        for j in 0..shape.1 {
            for k in 0..shape.2 {
                let (mut sw, mut swf) = (0.0, 0.0);
                for (dx, hx) in TENT_PULL.iter().enumerate() {
                    let Some(x) = (2 * i + dx).checked_sub(1).filter(|&x| x < na) else {
                        continue;
                    };
                    for (dy, hy) in TENT_PULL.iter().enumerate() {
                        let Some(y) = (2 * j + dy).checked_sub(1).filter(|&y| y < nb) else {
                            continue;
                        };
                        for (dz, hz) in TENT_PULL.iter().enumerate() {
                            let Some(z) = (2 * k + dz).checked_sub(1).filter(|&z| z < nc) else {
                                continue;
                            };
                            let id = fine.idx(x, y, z);
                            let h = hx * hy * hz * fine.w[id].min(1.0);
                            sw += h;
                            swf += h * fine.f[id];
                        }
                    }
                }
                let o = out.idx(i, j, k);
                out.w[o] = gain * sw;
                out.f[o] = if sw > 0.0 { swf / sw } else { 0.0 };
            }
        }
    }
    out
}

/// Coarse parents of fine index `i` with their push taps.
fn parents(i: usize, n_coarse: usize) -> [(usize, f64); 2] {
    if i & 1 == 0 {
        [(i / 2, TENT_PUSH[1]), (usize::MAX, 0.0)]
    } else {
        let hi = i.div_ceil(2);
        [
            (i / 2, TENT_PUSH[0]),
            if hi < n_coarse {
                (hi, TENT_PUSH[2])
            } else {
                (usize::MAX, 0.0)
            },
        ]
    }
}

fn push(fine: &mut Level, coarse: &Level) {
    let (na, nb, nc) = fine.shape;
    for a in 0..na {
        let pa = parents(a, coarse.shape.0);
        for b in 0..nb {
            let pb = parents(b, coarse.shape.1);
            for c in 0..nc {
                let pc = parents(c, coarse.shape.2);
                let (mut tw, mut tf) = (0.0, 0.0);
                for &(x, hx) in &pa {
                    if x == usize::MAX {
                        continue;
                    }
                    for &(y, hy) in &pb {
                        if y == usize::MAX {
                            continue;
                        }
                        for &(z, hz) in &pc {
                            if z == usize::MAX {
                                continue;
                            }
                            let h = hx * hy * hz;
                            tw += h;
                            tf += h * coarse.f[coarse.idx(x, y, z)];
                        }
                    }
                }
                let id = fine.idx(a, b, c);
                let w = fine.w[id].min(1.0);
                let tf = if tw > 0.0 { tf / tw } else { 0.0 };
                fine.f[id] = tf * (1.0 - w) + fine.f[id] * w;
                fine.w[id] = (1.0 - w) + w;
            }
        }
    }
}

/// Pull-push reconstruction of one channel from `(grid point, value)` samples. Samples at the
/// same point are averaged.
pub fn pull_push_channel(grid: &SampleGrid, samples: &[(usize, f64)]) -> Result<Vec<f64>> {
    pull_push_channel_with_gain(grid, samples, WEIGHT_GAIN)
}

/// [`pull_push_channel`] with an explicit pulled-weight gain (1 = (6.8) read literally).
pub fn pull_push_channel_with_gain(
    grid: &SampleGrid,
    samples: &[(usize, f64)],
    gain: f64,
) -> Result<Vec<f64>> {
    if !(gain.is_finite() && gain > 0.0) {
        return Err(SamplingError::InvalidParameter(format!(
            "weight gain {gain}"
        )));
    }
    if samples.is_empty() {
        return Err(SamplingError::InvalidParameter(
            "pull-push needs at least one sample per channel".into(),
        ));
    }
    let shape = grid.shape();
    let n = grid.len();
    let mut level = Level {
        shape,
        f: vec![0.0; n],
        w: vec![0.0; n],
    };
    let mut count = vec![0usize; n];
    for &(p, v) in samples {
        if p >= n {
            return Err(SamplingError::Dimension(format!("grid point {p} ≥ {n}")));
        }
        if !v.is_finite() {
            return Err(SamplingError::NonFinite("sample value".into()));
        }
        level.f[p] += v;
        count[p] += 1;
    }
    for p in 0..n {
        if count[p] > 0 {
            level.f[p] /= count[p] as f64;
            level.w[p] = 1.0;
        }
    }
    let mut pyramid = vec![level];
    while pyramid.last().map(|l| l.shape) != Some((1, 1, 1)) {
        let next = pull(pyramid.last().expect("non-empty pyramid"), gain);
        pyramid.push(next);
    }
    for r in (0..pyramid.len() - 1).rev() {
        let (lo, hi) = pyramid.split_at_mut(r + 1);
        push(&mut lo[r], &hi[0]);
    }
    Ok(pyramid.swap_remove(0).f)
}

/// Pull-push reconstruction of all three channels from `(grid point, channel, value)` samples
/// (thesis §6.4, eqs. 6.8–6.12).
///
/// Samples are placed on the finest level of a pyramid over the grid (weight `c = 1`). The pull
/// step builds coarser levels with the tent filter h̃ of (6.9) (1D taps ¼, ½, ¼, centred on
/// fine index `2i`); the push step fills gaps from the coarser level with the interpolating
/// tent h of (6.11) (1D taps ½, 1, ½) and blends by (6.12). Along an axis a level of size `n`
/// has a parent of size `⌈n/2⌉`; the pyramid ends at 1 × 1 × 1. At borders the push uses the
/// taps that exist, normalised (`tf / tw`).
///
/// Weights. The h̃ of (6.9) sums to 1, so a pulled weight can never exceed the confidence
/// `c = 1`, although the text says a value whose weight is larger than `c` ignores the coarser
/// level. Taken literally, a half-sampled neighbourhood then has weight ≈ ½ at every level and
/// (6.12) drags its values halfway towards ever coarser averages (measured: a 4× overestimate of
/// unsampled points between samples of a smooth region). The weights are therefore pulled with
/// the unnormalised tent (`WEIGHT_GAIN` = 8 = (½ + 1 + ½)³ times h̃, as in Gortler et al.'s
/// Lumigraph pull-push) and clamped to 1 in the blend; values are still normalised averages.
/// [`pull_push_channel_with_gain`] with gain 1 gives the literal reading.
///
/// # Examples
///
/// ```
/// use sampling::{pull_push, Domain, SampleGrid};
///
/// // a constant material sampled at every fifth grid point comes back constant everywhere
/// let grid = SampleGrid::new(9, 9, 18).unwrap();
/// let samples: Vec<_> = (0..grid.len())
///     .step_by(5)
///     .flat_map(|p| (0..3).map(move |ch| (p, ch, 0.2)))
///     .collect();
/// let table = pull_push(&grid, &samples, Domain::Log).unwrap();
/// assert!((0..grid.len()).all(|p| (table.get(0, p) - 0.2).abs() < 1e-9));
/// ```
pub fn pull_push(
    grid: &SampleGrid,
    samples: &[(usize, usize, f64)],
    domain: Domain,
) -> Result<GridTable> {
    let n = grid.len();
    let mut values = vec![0.0; 3 * n];
    for ch in 0..3 {
        let s: Vec<(usize, f64)> = samples
            .iter()
            .filter(|s| s.1 == ch)
            .map(|&(p, _, v)| {
                (
                    p,
                    match domain {
                        Domain::Linear => v.max(0.0),
                        Domain::Log => to_log(v),
                    },
                )
            })
            .collect();
        let out = pull_push_channel(grid, &s)?;
        for (o, v) in values[ch * n..(ch + 1) * n].iter_mut().zip(out) {
            *o = match domain {
                Domain::Linear => v.max(0.0),
                Domain::Log => from_log_clamped(v),
            };
        }
    }
    GridTable::new(*grid, values)
}
