//! X-junction candidates and the lattice they form: the part of the checkerboard detector
//! between the smoothed image and the labelled corner grid.

use crate::corners::GrayImage;
use std::collections::{HashMap, VecDeque};

/// One X-junction candidate.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct Candidate {
    /// Pixel position.
    pub p: [f64; 2],
    /// Saddle response.
    pub response: f32,
    /// Contrast on the ring (bright minus dark).
    pub contrast: f64,
    /// Angles of the two edge lines through the junction, radians in [0, π).
    pub lines: [f64; 2],
}

pub(crate) fn dist(a: &[f64; 2], b: &[f64; 2]) -> f64 {
    (a[0] - b[0]).hypot(a[1] - b[1])
}

/// Difference of two line angles (period π), in [0, π/2].
fn axial_diff(a: f64, b: f64) -> f64 {
    let d = (a - b).rem_euclid(std::f64::consts::PI);
    d.min(std::f64::consts::PI - d)
}

/// Ring test at (x, y), radius `rho`: contrast and the two edge-line angles, or `None` when
/// the ring does not show an X-junction.
pub(crate) fn ring_test(s: &GrayImage, x: f64, y: f64, rho: f64) -> Option<(f64, [f64; 2])> {
    use std::f64::consts::{PI, TAU};
    const N: usize = 48;
    let mut vals = [0f64; N];
    for (k, v) in vals.iter_mut().enumerate() {
        let a = k as f64 * TAU / N as f64;
        *v = s.sample(x + rho * a.cos(), y + rho * a.sin());
    }
    let lo = vals.iter().cloned().fold(f64::INFINITY, f64::min);
    let hi = vals.iter().cloned().fold(f64::NEG_INFINITY, f64::max);
    if !(hi > lo) {
        return None;
    }
    let mid = 0.5 * (lo + hi);
    let bits: Vec<bool> = vals.iter().map(|&v| v > mid).collect();
    let mut transitions = Vec::with_capacity(4);
    for k in 0..N {
        if bits[k] != bits[(k + N - 1) % N] {
            // Interpolated crossing of the mid level between samples k − 1 and k.
            let (a, b) = (vals[(k + N - 1) % N], vals[k]);
            let f = if b != a { (mid - a) / (b - a) } else { 0.5 };
            transitions.push(((k as f64 - 1.0 + f) * TAU / N as f64).rem_euclid(TAU));
            if transitions.len() > 4 {
                return None;
            }
        }
    }
    if transitions.len() != 4 {
        return None;
    }
    // Arcs of at least two samples.
    for i in 0..4 {
        let arc = (transitions[(i + 1) % 4] - transitions[i]).rem_euclid(TAU);
        if arc < 1.5 * TAU / N as f64 {
            return None;
        }
    }
    // Opposite transitions lie on one straight line through the centre.
    let mut lines = [0.0; 2];
    for (i, line) in lines.iter_mut().enumerate() {
        let (a, b) = (transitions[i], transitions[i + 2]);
        let off = ((b - a).rem_euclid(TAU) - PI).abs();
        if off > 25f64.to_radians() {
            return None;
        }
        let (s2, c2) = (
            (2.0 * a).sin() + (2.0 * b).sin(),
            (2.0 * a).cos() + (2.0 * b).cos(),
        );
        *line = (0.5 * s2.atan2(c2)).rem_euclid(PI);
    }
    if axial_diff(lines[0], lines[1]) < 12f64.to_radians() {
        return None;
    }
    Some((hi - lo, lines))
}

/// Saddle response Ixy² − Ixx·Iyy of a smoothed image (positive at X-junctions).
fn saddle_response(s: &GrayImage) -> Vec<f32> {
    let (w, h) = (s.width, s.height);
    let d = &s.data;
    let mut out = vec![0f32; w * h];
    for y in 1..h.saturating_sub(1) {
        for x in 1..w.saturating_sub(1) {
            let i = y * w + x;
            let c = d[i];
            let ixx = d[i + 1] - 2.0 * c + d[i - 1];
            let iyy = d[i + w] - 2.0 * c + d[i - w];
            let ixy = 0.25 * (d[i + w + 1] - d[i - w + 1] - d[i + w - 1] + d[i - w - 1]);
            out[i] = ixy * ixy - ixx * iyy;
        }
    }
    out
}

/// X-junction candidates of a smoothed image, strongest first: local maxima (radius `nms`) of
/// the saddle response above `fraction` of its maximum that pass the ring test at `rho` with
/// at least `min_contrast_fraction` of the image's 5–95 % range.
pub(crate) fn candidates(
    s: &GrayImage,
    nms: usize,
    rho: f64,
    fraction: f64,
    min_contrast_fraction: f64,
    limit: usize,
) -> Vec<Candidate> {
    let (w, h) = (s.width, s.height);
    if w < 2 * nms + 3 || h < 2 * nms + 3 {
        return Vec::new();
    }
    let resp = saddle_response(s);
    let max = resp.iter().cloned().fold(0f32, f32::max);
    if !(max > 0.0) {
        return Vec::new();
    }
    let thr = max * fraction as f32;
    let (lo, hi) = {
        let mut v: Vec<f32> = s.data.iter().step_by(7).cloned().collect();
        v.sort_by(|a, b| a.total_cmp(b));
        (v[v.len() / 20] as f64, v[v.len() - 1 - v.len() / 20] as f64)
    };
    let min_contrast = min_contrast_fraction * (hi - lo);
    let r = nms;
    let border = (rho.ceil() as usize + 1).max(r);
    let mut maxima: Vec<(f32, usize, usize)> = Vec::new();
    for y in border..h.saturating_sub(border) {
        for x in border..w.saturating_sub(border) {
            let v = resp[y * w + x];
            if v < thr {
                continue;
            }
            let mut is_max = true;
            'nms: for yy in y - r..=y + r {
                for xx in x - r..=x + r {
                    let o = resp[yy * w + xx];
                    if o > v || (o == v && (yy, xx) < (y, x)) {
                        is_max = false;
                        break 'nms;
                    }
                }
            }
            if is_max {
                maxima.push((v, x, y));
            }
        }
    }
    maxima.sort_by(|a, b| b.0.total_cmp(&a.0));
    let mut found = Vec::new();
    for (v, x, y) in maxima {
        if found.len() >= limit {
            break;
        }
        if let Some((contrast, lines)) = ring_test(s, x as f64, y as f64, rho) {
            if contrast >= min_contrast {
                found.push(Candidate {
                    p: [x as f64, y as f64],
                    response: v,
                    contrast,
                    lines,
                });
            }
        }
    }
    found
}

/// Whether the segment `p`–`q` is a square edge: the image on its two sides, at 30 % of its
/// length from its midpoint, differs by at least `min_step`; and the samples along it, off its
/// ends, do not.
pub(crate) fn is_square_edge(s: &GrayImage, p: &[f64; 2], q: &[f64; 2], min_step: f64) -> bool {
    let d = [q[0] - p[0], q[1] - p[1]];
    let n = [-d[1] * 0.3, d[0] * 0.3];
    let mut steps = [0.0; 2];
    for (k, t) in [0.35, 0.65].iter().enumerate() {
        let m = [p[0] + t * d[0], p[1] + t * d[1]];
        let a = s.sample(m[0] + n[0], m[1] + n[1]);
        let b = s.sample(m[0] - n[0], m[1] - n[1]);
        steps[k] = a - b;
    }
    // Both halves of the edge separate the same two squares.
    steps[0].abs() >= min_step && steps[1].abs() >= min_step && steps[0] * steps[1] > 0.0
}

/// A lattice of corner positions keyed by lattice coordinates.
pub(crate) type Lattice = HashMap<(i32, i32), [f64; 2]>;

/// What the grower needs besides the candidates.
pub(crate) struct Grower<'a> {
    /// The smoothed image (ring and edge tests).
    pub smooth: &'a GrayImage,
    /// Ring radius.
    pub rho: f64,
    /// Candidates.
    pub cand: &'a [Candidate],
    /// Largest lattice worth growing.
    pub max_nodes: usize,
    /// Re-locates a corner near a predicted position (for corners without a candidate):
    /// (prediction, search radius) → position.
    pub relocate: &'a dyn Fn([f64; 2], f64) -> Option<[f64; 2]>,
}

impl Grower<'_> {
    /// The neighbour of candidate `i` along line `line` of it (either sense): nearest candidate
    /// in that direction whose joining segment is a square edge.
    fn seed_neighbour(&self, i: usize, line: f64) -> Option<usize> {
        let c = &self.cand[i];
        let mut best: Option<(f64, usize)> = None;
        for (j, o) in self.cand.iter().enumerate() {
            if j == i {
                continue;
            }
            let d = dist(&c.p, &o.p);
            if d < 3.0 || best.is_some_and(|(bd, _)| d >= bd) {
                continue;
            }
            let a = (o.p[1] - c.p[1]).atan2(o.p[0] - c.p[0]);
            if axial_diff(a, line) > 20f64.to_radians() {
                continue;
            }
            let step = 0.35 * c.contrast.min(o.contrast);
            if is_square_edge(self.smooth, &c.p, &o.p, step) {
                best = Some((d, j));
            }
        }
        best.map(|b| b.1)
    }

    /// Grows the lattice from candidate `seed`; `None` without two seed neighbours.
    pub fn grow(&self, seed: usize) -> Option<Lattice> {
        let c0 = &self.cand[seed];
        let n1 = self.seed_neighbour(seed, c0.lines[0])?;
        let n2 = self.seed_neighbour(seed, c0.lines[1])?;
        let p0 = c0.p;
        let d = [
            [self.cand[n1].p[0] - p0[0], self.cand[n1].p[1] - p0[1]],
            [self.cand[n2].p[0] - p0[0], self.cand[n2].p[1] - p0[1]],
        ];
        let contrast = c0.contrast;
        let mut grid: Lattice = HashMap::new();
        let mut used = vec![false; self.cand.len()];
        for (k, i) in [((0, 0), seed), ((1, 0), n1), ((0, 1), n2)] {
            grid.insert(k, self.cand[i].p);
            used[i] = true;
        }
        let mut queue: VecDeque<(i32, i32)> = [(0, 0), (1, 0), (0, 1)].into();
        while let Some((a, b)) = queue.pop_front() {
            if grid.len() >= self.max_nodes {
                break;
            }
            for (da, db) in [(1, 0), (-1, 0), (0, 1), (0, -1)] {
                let target = (a + da, b + db);
                if grid.contains_key(&target) {
                    continue;
                }
                let p = grid[&(a, b)];
                let step = if let Some(q) = grid.get(&(a - da, b - db)) {
                    [p[0] - q[0], p[1] - q[1]]
                } else {
                    let perp = (db, da);
                    [1, -1, 2, -2]
                        .iter()
                        .find_map(|&k| {
                            let s0 = grid.get(&(a + k * perp.0, b + k * perp.1))?;
                            let s1 = grid.get(&(a + k * perp.0 + da, b + k * perp.1 + db))?;
                            Some([s1[0] - s0[0], s1[1] - s0[1]])
                        })
                        .unwrap_or_else(|| {
                            let v = if da != 0 { d[0] } else { d[1] };
                            let s = (da + db) as f64;
                            [s * v[0], s * v[1]]
                        })
                };
                let len = step[0].hypot(step[1]);
                let pred = [p[0] + step[0], p[1] + step[1]];
                let tol = 0.3 * len;
                let min_step = 0.35 * contrast;
                let mut best: Option<(f64, usize)> = None;
                for (j, o) in self.cand.iter().enumerate() {
                    if used[j] {
                        continue;
                    }
                    let e = dist(&o.p, &pred);
                    if e < tol && best.is_none_or(|(be, _)| e < be) {
                        best = Some((e, j));
                    }
                }
                let hit = match best {
                    Some((_, j)) if is_square_edge(self.smooth, &p, &self.cand[j].p, min_step) => {
                        used[j] = true;
                        Some(self.cand[j].p)
                    }
                    _ => (self.relocate)(pred, tol).filter(|q| {
                        dist(q, &pred) < tol
                            && grid.values().all(|g| dist(g, q) > 0.5 * len)
                            && ring_test(self.smooth, q[0], q[1], self.rho)
                                .is_some_and(|(c, _)| c >= 0.5 * contrast)
                            && is_square_edge(self.smooth, &p, q, min_step)
                    }),
                };
                if let Some(q) = hit {
                    grid.insert(target, q);
                    queue.push_back(target);
                }
            }
        }
        Some(grid)
    }
}

/// The complete `nx × ny` windows of a lattice (either orientation): (a0, b0, transposed).
pub(crate) fn complete_windows(grid: &Lattice, nx: usize, ny: usize) -> Vec<(i32, i32, bool)> {
    let amin = grid.keys().map(|k| k.0).min().unwrap_or(0);
    let amax = grid.keys().map(|k| k.0).max().unwrap_or(0);
    let bmin = grid.keys().map(|k| k.1).min().unwrap_or(0);
    let bmax = grid.keys().map(|k| k.1).max().unwrap_or(0);
    let mut out = Vec::new();
    let orientations: &[(usize, usize, bool)] = if nx == ny {
        &[(nx, ny, false)]
    } else {
        &[(nx, ny, false), (ny, nx, true)]
    };
    for &(wa, wb, t) in orientations {
        let (wa, wb) = (wa as i32, wb as i32);
        for a0 in amin..=amax - wa + 1 {
            for b0 in bmin..=bmax - wb + 1 {
                let full = (a0..a0 + wa).all(|a| (b0..b0 + wb).all(|b| grid.contains_key(&(a, b))));
                if full {
                    out.push((a0, b0, t));
                }
            }
        }
    }
    out
}
