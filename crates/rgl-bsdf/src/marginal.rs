//! Bilinearly interpolated 2D densities on the unit square, conditioned on parameters, and
//! their sampling warp (marginal in `y`, then conditional in `x`), computed as the renderers
//! that read `.bsdf` files compute them, so that a file is evaluated here as it is there.
//!
//! A grid of `w × h` node values covers `[0, 1]²` (node `(i, j)` at `(i / (w − 1), j / (h − 1))`);
//! one grid per combination of parameter values (a *slice*), the last parameter varying
//! fastest. Between parameter values the slices are blended linearly; outside the range the
//! nearest slice is used.

/// A parameterised density (or plain interpolant) on the unit square.
#[derive(Debug, Clone)]
pub(crate) struct Marginal2D {
    w: usize,
    h: usize,
    params: Vec<Vec<f32>>,
    strides: Vec<usize>,
    data: Vec<f32>,
    marg: Vec<f32>,
    cond: Vec<f32>,
    normalized: bool,
}

/// One parameter dimension's lower slice index and blending weights.
type Blend = (usize, [f32; 2]);

impl Marginal2D {
    /// Builds the warp of `data` (`slices × h × w` values, parameters `params[d]` for each
    /// conditioning dimension `d`, slowest first). `normalize` scales each slice to unit
    /// integral; `sampling` builds the CDFs of [`sample`](Self::sample) and
    /// [`invert`](Self::invert).
    pub(crate) fn new(
        data: &[f32],
        w: usize,
        h: usize,
        params: Vec<Vec<f32>>,
        normalize: bool,
        sampling: bool,
    ) -> Marginal2D {
        assert!(w >= 2 && h >= 2, "a grid needs two nodes per axis");
        let mut strides = vec![0; params.len()];
        let mut slices = 1;
        for d in (0..params.len()).rev() {
            strides[d] = if params[d].len() > 1 { slices } else { 0 };
            slices *= params[d].len();
        }
        let n = w * h;
        assert_eq!(data.len(), slices * n, "data size");
        let (mut out, mut marg, mut cond) = (Vec::with_capacity(data.len()), vec![], vec![]);
        let (sx, sy) = (0.5 / (w - 1) as f64, 0.5 / (h - 1) as f64);
        for s in 0..slices {
            let d = &data[s * n..(s + 1) * n];
            let mut norm = 1.0f64;
            if sampling {
                let mut sums = vec![0.0f64; h];
                let row0 = cond.len();
                for (y, sum) in sums.iter_mut().enumerate() {
                    let mut acc = 0.0f64;
                    for x in 0..w - 1 {
                        acc += sx * (d[y * w + x] as f64 + d[y * w + x + 1] as f64);
                        cond.push(acc as f32);
                    }
                    *sum = acc;
                }
                let m0 = marg.len();
                let mut acc = 0.0f64;
                for y in 0..h - 1 {
                    acc += sy * (sums[y] + sums[y + 1]);
                    marg.push(acc as f32);
                }
                if normalize {
                    norm = 1.0 / acc;
                }
                for v in &mut cond[row0..] {
                    *v = (*v as f64 * norm) as f32;
                }
                for v in &mut marg[m0..] {
                    *v = (*v as f64 * norm) as f32;
                }
            } else if normalize {
                let mut sum = 0.0f64;
                for y in 0..h - 1 {
                    for x in 0..w - 1 {
                        let i = y * w + x;
                        sum +=
                            d[i] as f64 + d[i + 1] as f64 + d[i + w] as f64 + d[i + w + 1] as f64;
                    }
                }
                norm = 1.0 / (sx * sy * sum);
            }
            out.extend(d.iter().map(|&v| (v as f64 * norm) as f32));
        }
        Marginal2D {
            w,
            h,
            params,
            strides,
            data: out,
            marg,
            cond,
            normalized: normalize,
        }
    }

    fn blends(&self, param: &[f64]) -> (usize, Vec<Blend>) {
        let mut offset = 0;
        let mut blends = Vec::with_capacity(self.params.len());
        for (d, values) in self.params.iter().enumerate() {
            if values.len() == 1 {
                blends.push((0, [1.0, 0.0]));
                continue;
            }
            let p = param[d] as f32;
            // the interval [values[i], values[i + 1]] holding p, clamped to the ends
            let i = values[..values.len() - 1]
                .partition_point(|&v| v <= p)
                .saturating_sub(1)
                .min(values.len() - 2);
            let (p0, p1) = (values[i], values[i + 1]);
            let t = ((p - p0) / (p1 - p0)).clamp(0.0, 1.0);
            blends.push((i, [1.0 - t, t]));
            offset += self.strides[d] * i;
        }
        (offset, blends)
    }

    /// Value of `table` (one of data/marg/cond, `size` entries per slice) at `index` of the
    /// slice at `offset`, blended over the parameter dimensions.
    fn lookup(
        &self,
        table: &[f32],
        size: usize,
        offset: usize,
        blends: &[Blend],
        index: usize,
    ) -> f64 {
        let dims = blends.len();
        let mut total = 0.0f64;
        for corner in 0..(1usize << dims) {
            let mut weight = 1.0f64;
            let mut slice = offset;
            for (d, (_, w)) in blends.iter().enumerate() {
                let upper = (corner >> (dims - 1 - d)) & 1;
                weight *= w[upper] as f64;
                slice += upper * self.strides[d];
            }
            if weight != 0.0 {
                total += weight * table[slice * size + index] as f64;
            }
        }
        total
    }

    /// The interpolated (and, if normalized, unit-integral) density at `pos`.
    pub(crate) fn eval(&self, pos: [f64; 2], param: &[f64]) -> f64 {
        let (offset, blends) = self.blends(param);
        let (w, h) = (self.w, self.h);
        let x = pos[0].clamp(0.0, 1.0) * (w - 1) as f64;
        let y = pos[1].clamp(0.0, 1.0) * (h - 1) as f64;
        let (i, j) = ((x as usize).min(w - 2), (y as usize).min(h - 2));
        let (fx, fy) = (x - i as f64, y - j as f64);
        let n = w * h;
        let at = |k: usize| self.lookup(&self.data, n, offset, &blends, k);
        let k = j * w + i;
        let (v00, v10, v01, v11) = (at(k), at(k + 1), at(k + w), at(k + w + 1));
        (1.0 - fy) * ((1.0 - fx) * v00 + fx * v10) + fy * ((1.0 - fx) * v01 + fx * v11)
    }

    /// Warps a uniform point of the unit square to the density; returns the point and its
    /// density.
    pub(crate) fn sample(&self, u: [f64; 2], param: &[f64]) -> ([f64; 2], f64) {
        let (offset, blends) = self.blends(param);
        let (w, h) = (self.w, self.h);
        let (nm, nc, nd) = (h - 1, h * (w - 1), w * h);
        let eps = f32::EPSILON as f64;
        let (mut sx, mut sy) = (u[0].clamp(eps, 1.0 - eps), u[1].clamp(eps, 1.0 - eps));
        let marg = |k: usize| self.lookup(&self.marg, nm, offset, &blends, k);
        if !self.normalized {
            sy *= marg(nm - 1);
        }
        // the first row whose cumulative mass reaches sy
        let row = lower_bound(nm, |k| marg(k) < sy);
        if row > 0 {
            sy -= marg(row - 1);
        }
        let cond = |k: usize| self.lookup(&self.cond, nc, offset, &blends, k);
        let oc = row * (w - 1);
        let (r0, r1) = (cond(oc + w - 2), cond(oc + 2 * (w - 1) - 1));
        sy = sample_segment(sy, (h - 1) as f64, r0, r1);
        sx *= r0 + (r1 - r0) * sy;
        let cond_at = |k: usize| {
            let (a, b) = (cond(oc + k), cond(oc + w - 1 + k));
            a + (b - a) * sy
        };
        let col = lower_bound(w - 1, |k| cond_at(k) < sx);
        if col > 0 {
            sx -= cond_at(col - 1);
        }
        let at = |k: usize| self.lookup(&self.data, nd, offset, &blends, k);
        let k = row * w + col;
        let (v00, v10, v01, v11) = (at(k), at(k + 1), at(k + w), at(k + w + 1));
        let c0 = v00 + (v01 - v00) * sy;
        let c1 = v10 + (v11 - v10) * sy;
        sx = sample_segment(sx, (w - 1) as f64, c0, c1);
        (
            [
                (col as f64 + sx) / (w - 1) as f64,
                (row as f64 + sy) / (h - 1) as f64,
            ],
            c0 + (c1 - c0) * sx,
        )
    }

    /// The inverse of [`sample`](Self::sample): the uniform point that warps to `pos`, and the
    /// density at `pos`.
    pub(crate) fn invert(&self, pos: [f64; 2], param: &[f64]) -> ([f64; 2], f64) {
        let (offset, blends) = self.blends(param);
        let (w, h) = (self.w, self.h);
        let (nm, nc, nd) = (h - 1, h * (w - 1), w * h);
        let x = pos[0].clamp(0.0, 1.0) * (w - 1) as f64;
        let y = pos[1].clamp(0.0, 1.0) * (h - 1) as f64;
        let (i, j) = ((x as usize).min(w - 2), (y as usize).min(h - 2));
        let (mut fx, mut fy) = (x - i as f64, y - j as f64);
        let at = |k: usize| self.lookup(&self.data, nd, offset, &blends, k);
        let k = j * w + i;
        let (v00, v10, v01, v11) = (at(k), at(k + 1), at(k + w), at(k + w + 1));
        let c0 = v00 + (v01 - v00) * fy;
        let c1 = v10 + (v11 - v10) * fy;
        let pdf = c0 + (c1 - c0) * fx;
        fx = invert_segment(fx, 1.0 / (w - 1) as f64, c0, c1);
        let cond = |k: usize| self.lookup(&self.cond, nc, offset, &blends, k);
        let oc = j * (w - 1);
        if i > 0 {
            let (a, b) = (cond(oc + i - 1), cond(oc + w - 1 + i - 1));
            fx += a + (b - a) * fy;
        }
        let (r0, r1) = (cond(oc + w - 2), cond(oc + 2 * (w - 1) - 1));
        fx /= r0 + (r1 - r0) * fy;
        fy = invert_segment(fy, 1.0 / (h - 1) as f64, r0, r1);
        let marg = |k: usize| self.lookup(&self.marg, nm, offset, &blends, k);
        if j > 0 {
            fy += marg(j - 1);
        }
        if !self.normalized {
            fy /= marg(nm - 1);
        }
        ([fx, fy], pdf)
    }
}

/// The first index in `0..n` where `below` is false (`n − 1` at most).
fn lower_bound(n: usize, below: impl Fn(usize) -> bool) -> usize {
    let (mut lo, mut hi) = (0, n - 1);
    while lo < hi {
        let mid = (lo + hi) / 2;
        if below(mid) {
            lo = mid + 1;
        } else {
            hi = mid;
        }
    }
    lo
}

/// Inverts the integral of the linear density `v0 → v1` over a segment of `1 / inv_width`.
fn sample_segment(u: f64, inv_width: f64, v0: f64, v1: f64) -> f64 {
    let varies = (v0 - v1).abs() > 1e-4 * (v0 + v1);
    let divisor = if varies { v0 - v1 } else { v0 + v1 };
    let mut s = u * 2.0 * inv_width;
    if varies {
        s = v0 - (v0 * v0 + s * (v1 - v0)).max(0.0).sqrt();
    }
    if divisor != 0.0 {
        s /= divisor;
    }
    s
}

/// The integral of the linear density `v0 → v1` from 0 to `t` of a segment of `width`.
fn invert_segment(t: f64, width: f64, v0: f64, v1: f64) -> f64 {
    t * (v0 + (v1 - v0) * 0.5 * t) * width
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{Rng, SeedableRng};

    fn bumpy(w: usize, h: usize, slices: usize) -> Vec<f32> {
        (0..slices * w * h)
            .map(|k| {
                let (s, j, i) = (k / (w * h), (k / w) % h, k % w);
                1.0 + (i as f32 * 0.7 + s as f32).sin().abs() * 3.0 + j as f32 * 0.1
            })
            .collect()
    }

    #[test]
    fn invert_undoes_sample_and_the_densities_agree() {
        let (w, h) = (7, 5);
        let m = Marginal2D::new(
            &bumpy(w, h, 6),
            w,
            h,
            vec![vec![0.0, 1.0], vec![0.0, 0.5, 2.0]],
            true,
            true,
        );
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(5);
        for _ in 0..2000 {
            let u = [rng.gen::<f64>(), rng.gen::<f64>()];
            let p = [rng.gen::<f64>(), rng.gen::<f64>() * 2.0];
            let (x, pdf) = m.sample(u, &p);
            let (back, pdf2) = m.invert(x, &p);
            assert!(
                (back[0] - u[0]).abs() < 1e-4 && (back[1] - u[1]).abs() < 1e-4,
                "{u:?} → {x:?} → {back:?}"
            );
            assert!((pdf - pdf2).abs() < 1e-4 * pdf.max(1.0));
            assert!((m.eval(x, &p) - pdf).abs() < 1e-4 * pdf.max(1.0));
        }
    }

    #[test]
    fn a_normalized_density_integrates_to_one() {
        let (w, h) = (9, 6);
        let m = Marginal2D::new(&bumpy(w, h, 2), w, h, vec![vec![0.0, 1.0]], true, true);
        for p in [0.0, 0.3, 1.0] {
            let n = 400;
            let mut sum = 0.0;
            for a in 0..n {
                for b in 0..n {
                    let pos = [(a as f64 + 0.5) / n as f64, (b as f64 + 0.5) / n as f64];
                    sum += m.eval(pos, &[p]);
                }
            }
            assert!(
                (sum / (n * n) as f64 - 1.0).abs() < 1e-3,
                "{p}: {}",
                sum / (n * n) as f64
            );
        }
    }

    #[test]
    fn a_plain_interpolant_returns_the_node_values() {
        let (w, h) = (4, 3);
        let data: Vec<f32> = (0..w * h).map(|k| k as f32).collect();
        let m = Marginal2D::new(&data, w, h, vec![], false, false);
        for j in 0..h {
            for i in 0..w {
                let pos = [i as f64 / (w - 1) as f64, j as f64 / (h - 1) as f64];
                assert!((m.eval(pos, &[]) - (j * w + i) as f64).abs() < 1e-6);
            }
        }
    }
}
