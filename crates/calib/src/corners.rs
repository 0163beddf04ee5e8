//! Checkerboard inner-corner detection in raw Bayer frames: colour-balanced (or green-channel)
//! image, saddle-point response (negative Hessian determinant), ring test for X-junctions, grid growing and
//! labelling, sub-pixel refinement by the gradient-orthogonality condition.

use crate::error::{CalibError, CalibResult};
use crate::frames::FlatField;
use crate::intrinsics::BoardGeometry;
use gantry_hal::BayerFrame;
use serde::{Deserialize, Serialize};
use std::collections::HashMap;

/// A single-channel image, row-major, pixel centres at integer coordinates.
#[derive(Debug, Clone, PartialEq)]
pub struct GrayImage {
    /// Columns.
    pub width: usize,
    /// Rows.
    pub height: usize,
    /// Samples, `width * height`.
    pub data: Vec<f32>,
}

impl GrayImage {
    #[inline]
    fn at(&self, x: usize, y: usize) -> f32 {
        self.data[y * self.width + x]
    }

    /// Bilinear sample at (`x`, `y`), clamped to the image.
    pub fn sample(&self, x: f64, y: f64) -> f64 {
        let x = x.clamp(0.0, (self.width - 1) as f64);
        let y = y.clamp(0.0, (self.height - 1) as f64);
        let (x0, y0) = (x.floor() as usize, y.floor() as usize);
        let (x1, y1) = ((x0 + 1).min(self.width - 1), (y0 + 1).min(self.height - 1));
        let (fx, fy) = (x - x0 as f64, y - y0 as f64);
        let a = self.at(x0, y0) as f64 * (1.0 - fx) + self.at(x1, y0) as f64 * fx;
        let b = self.at(x0, y1) as f64 * (1.0 - fx) + self.at(x1, y1) as f64 * fx;
        a * (1.0 - fy) + b * fy
    }
}

/// The photosite values of `frame`, each divided by its gain in `flat` when given.
fn photosites(frame: &BayerFrame, flat: Option<&FlatField>) -> CalibResult<Vec<f32>> {
    match flat {
        Some(ff) => ff.correct(frame),
        None => {
            frame
                .validate()
                .map_err(|e| CalibError::Invalid(format!("target frame: {e}")))?;
            Ok(frame.data.iter().map(|&v| v as f32).collect())
        }
    }
}

/// Green-channel image of a Bayer frame (flat-fielded by `flat` when given): green photosites
/// as they are, the others the mean of their green 4-neighbours.
pub fn green_image(frame: &BayerFrame, flat: Option<&FlatField>) -> CalibResult<GrayImage> {
    let raw = photosites(frame, flat)?;
    let (w, h) = (frame.width, frame.height);
    let mut data = vec![0f32; w * h];
    for y in 0..h {
        for x in 0..w {
            data[y * w + x] = if frame.channel_at(x, y) == 1 {
                raw[y * w + x]
            } else {
                let mut s = 0.0f32;
                let mut n = 0.0f32;
                let nb = [
                    (x.wrapping_sub(1), y),
                    (x + 1, y),
                    (x, y.wrapping_sub(1)),
                    (x, y + 1),
                ];
                for (nx, ny) in nb {
                    if nx < w && ny < h && frame.channel_at(nx, ny) == 1 {
                        s += raw[ny * w + nx];
                        n += 1.0;
                    }
                }
                if n > 0.0 {
                    s / n
                } else {
                    raw[y * w + x]
                }
            };
        }
    }
    Ok(GrayImage {
        width: w,
        height: h,
        data,
    })
}

/// Grey image of a Bayer frame of a grey target (flat-fielded by `flat` when given): every
/// photosite, its channel mapped affinely onto the green channel's scale (the channels' 2nd and
/// 98th percentiles matched), so that all photosites carry independent samples of the same
/// pattern.
pub fn balanced_image(frame: &BayerFrame, flat: Option<&FlatField>) -> CalibResult<GrayImage> {
    let raw = photosites(frame, flat)?;
    let (w, h) = (frame.width, frame.height);
    let mut per: [Vec<f32>; 3] = [Vec::new(), Vec::new(), Vec::new()];
    for y in 0..h {
        for x in 0..w {
            per[frame.channel_at(x, y)].push(raw[y * w + x]);
        }
    }
    let levels = |v: &mut Vec<f32>| -> Option<(f64, f64)> {
        if v.len() < 16 {
            return None;
        }
        v.sort_unstable_by(f32::total_cmp);
        let q = |p: f64| v[((v.len() - 1) as f64 * p).round() as usize] as f64;
        Some((q(0.02), q(0.98)))
    };
    let g = levels(&mut per[1]);
    let mut map = [(1.0f32, 0.0f32); 3];
    if let Some((g0, g1)) = g {
        for c in [0usize, 2] {
            if let Some((c0, c1)) = levels(&mut per[c]) {
                if c1 - c0 > 0.05 * (g1 - g0) && g1 > g0 {
                    let a = (g1 - g0) / (c1 - c0);
                    map[c] = (a as f32, (g0 - a * c0) as f32);
                }
            }
        }
    }
    let mut data = vec![0f32; w * h];
    for y in 0..h {
        for x in 0..w {
            let (a, b) = map[frame.channel_at(x, y)];
            data[y * w + x] = a * raw[y * w + x] + b;
        }
    }
    Ok(GrayImage {
        width: w,
        height: h,
        data,
    })
}

/// Separable Gaussian blur with clamped borders.
pub fn gaussian_blur(img: &GrayImage, sigma: f64) -> GrayImage {
    if sigma <= 0.0 {
        return img.clone();
    }
    let r = (3.0 * sigma).ceil() as isize;
    let kernel: Vec<f32> = (-r..=r)
        .map(|i| (-(i * i) as f64 / (2.0 * sigma * sigma)).exp() as f32)
        .collect();
    let ksum: f32 = kernel.iter().sum();
    let kernel: Vec<f32> = kernel.iter().map(|k| k / ksum).collect();
    let (w, h) = (img.width as isize, img.height as isize);
    let mut tmp = vec![0f32; img.data.len()];
    for y in 0..h {
        for x in 0..w {
            let mut acc = 0.0;
            for (k, kv) in kernel.iter().enumerate() {
                let xx = (x + k as isize - r).clamp(0, w - 1);
                acc += kv * img.data[(y * w + xx) as usize];
            }
            tmp[(y * w + x) as usize] = acc;
        }
    }
    let mut out = vec![0f32; img.data.len()];
    for y in 0..h {
        for x in 0..w {
            let mut acc = 0.0;
            for (k, kv) in kernel.iter().enumerate() {
                let yy = (y + k as isize - r).clamp(0, h - 1);
                acc += kv * tmp[(yy * w + x) as usize];
            }
            out[(y * w + x) as usize] = acc;
        }
    }
    GrayImage {
        width: img.width,
        height: img.height,
        data: out,
    }
}

/// Settings of the corner detector.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct CornerOptions {
    /// Gaussian smoothing before the saddle response, pixels.
    pub detect_sigma_px: f64,
    /// Gaussian smoothing before sub-pixel refinement, pixels.
    pub refine_sigma_px: f64,
    /// Sub-pixel window radius as a fraction of the local square size.
    pub window_fraction: f64,
    /// Saddle candidates below this fraction of the strongest response are ignored.
    pub response_fraction: f64,
    /// Sub-pixel method.
    pub subpixel: SubpixelMethod,
    /// Gaussian scale of the saddle-point refinement as a fraction of the local square size
    /// (distance to the nearest neighbouring corner).
    pub saddle_fraction: f64,
    /// Upper bound of the saddle-refinement scale, pixels (bounds the cost on large squares).
    pub max_saddle_sigma_px: f64,
    /// Which photosites the detector looks at.
    #[serde(default)]
    pub image: CornerImage,
}

/// The single-channel image the corners are found in.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum CornerImage {
    /// Every photosite, each colour channel mapped onto the green channel's scale
    /// ([`balanced_image`]); for grey targets. Twice the independent samples of `Green`: the
    /// corner error falls by about √2.
    #[default]
    Balanced,
    /// Green photosites, the others interpolated from them ([`green_image`]).
    Green,
}

/// How corners are refined to sub-pixel accuracy.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum SubpixelMethod {
    /// Gradients in a window are orthogonal to the vector from the corner (Förstner).
    GradientOrthogonality,
    /// Stationary point of the Gaussian-smoothed image, found by Newton iteration with the
    /// smoothing evaluated at the sub-pixel position (exact for a point-symmetric X-junction).
    Saddle,
}

impl Default for CornerOptions {
    fn default() -> Self {
        Self {
            detect_sigma_px: 1.5,
            refine_sigma_px: 1.0,
            window_fraction: 0.4,
            response_fraction: 0.03,
            subpixel: SubpixelMethod::Saddle,
            saddle_fraction: 0.25,
            max_saddle_sigma_px: 12.0,
            image: CornerImage::Balanced,
        }
    }
}

/// Saddle response Ixy² − Ixx·Iyy of a smoothed image (positive at X-junctions).
fn saddle_response(s: &GrayImage) -> Vec<f32> {
    let (w, h) = (s.width, s.height);
    let mut out = vec![0f32; w * h];
    for y in 1..h.saturating_sub(1) {
        for x in 1..w.saturating_sub(1) {
            let c = s.at(x, y);
            let ixx = s.at(x + 1, y) - 2.0 * c + s.at(x - 1, y);
            let iyy = s.at(x, y + 1) - 2.0 * c + s.at(x, y - 1);
            let ixy = 0.25
                * (s.at(x + 1, y + 1) - s.at(x + 1, y - 1) - s.at(x - 1, y + 1)
                    + s.at(x - 1, y - 1));
            out[y * w + x] = ixy * ixy - ixx * iyy;
        }
    }
    out
}

/// Ring test: on a circle of radius `rho` around (x, y) the image alternates
/// dark/bright/dark/bright (four transitions, each arc at least two samples long) with a
/// contrast of at least `min_contrast`.
fn is_x_junction(s: &GrayImage, x: f64, y: f64, rho: f64, min_contrast: f64) -> bool {
    const N: usize = 48;
    let vals: Vec<f64> = (0..N)
        .map(|k| {
            let a = k as f64 * std::f64::consts::TAU / N as f64;
            s.sample(x + rho * a.cos(), y + rho * a.sin())
        })
        .collect();
    let lo = vals.iter().cloned().fold(f64::INFINITY, f64::min);
    let hi = vals.iter().cloned().fold(f64::NEG_INFINITY, f64::max);
    if hi - lo < min_contrast {
        return false;
    }
    let mid = 0.5 * (lo + hi);
    let bits: Vec<bool> = vals.iter().map(|&v| v > mid).collect();
    let start = match (0..N).find(|&k| bits[k] != bits[(k + N - 1) % N]) {
        Some(k) => k,
        None => return false,
    };
    let mut runs = Vec::new();
    let mut len = 0;
    for k in 0..N {
        let i = (start + k) % N;
        if k > 0 && bits[i] != bits[(i + N - 1) % N] {
            runs.push(len);
            len = 0;
        }
        len += 1;
    }
    runs.push(len);
    runs.len() == 4 && runs.iter().all(|&r| r >= 2)
}

/// X-junction candidates (pixel positions) of a smoothed image, strongest first.
fn candidates(s: &GrayImage, opts: &CornerOptions, limit: usize) -> Vec<[f64; 2]> {
    let (w, h) = (s.width, s.height);
    let resp = saddle_response(s);
    let max = resp.iter().cloned().fold(0f32, f32::max);
    if !(max > 0.0) {
        return Vec::new();
    }
    let thr = max * opts.response_fraction as f32;
    let r = (2.0 * opts.detect_sigma_px).ceil().max(2.0) as usize;
    let (lo, hi) = {
        let mut v: Vec<f32> = s.data.iter().step_by(7).cloned().collect();
        v.sort_by(|a, b| a.total_cmp(b));
        (v[v.len() / 20] as f64, v[v.len() - 1 - v.len() / 20] as f64)
    };
    let min_contrast = 0.25 * (hi - lo);
    let rho = (3.0 * opts.detect_sigma_px).max(4.0);
    let mut found: Vec<(f32, [f64; 2])> = Vec::new();
    for y in r..h.saturating_sub(r) {
        for x in r..w.saturating_sub(r) {
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
            if is_max && is_x_junction(s, x as f64, y as f64, rho, min_contrast) {
                found.push((v, [x as f64, y as f64]));
            }
        }
    }
    found.sort_by(|a, b| b.0.total_cmp(&a.0));
    found.truncate(limit);
    found.into_iter().map(|f| f.1).collect()
}

fn dist(a: &[f64; 2], b: &[f64; 2]) -> f64 {
    ((a[0] - b[0]).powi(2) + (a[1] - b[1]).powi(2)).sqrt()
}

/// Seeds (centre, first neighbour, second neighbour) to try for lattice growing: the
/// candidates nearest the centroid, each with its nearest neighbour and the next few
/// non-collinear neighbours.
fn lattice_seeds(c: &[[f64; 2]]) -> Vec<(usize, usize, usize)> {
    let mut out = Vec::new();
    if c.len() < 4 {
        return out;
    }
    let n = c.len() as f64;
    let cen = c
        .iter()
        .fold([0.0, 0.0], |a, p| [a[0] + p[0] / n, a[1] + p[1] / n]);
    let mut seeds: Vec<usize> = (0..c.len()).collect();
    seeds.sort_by(|&i, &j| dist(&c[i], &cen).total_cmp(&dist(&c[j], &cen)));
    for &seed in seeds.iter().take(3) {
        let mut others: Vec<usize> = (0..c.len()).filter(|&i| i != seed).collect();
        others.sort_by(|&i, &j| dist(&c[i], &c[seed]).total_cmp(&dist(&c[j], &c[seed])));
        let n1 = others[0];
        let d1 = [c[n1][0] - c[seed][0], c[n1][1] - c[seed][1]];
        let l1 = dist(&c[n1], &c[seed]);
        let second: Vec<usize> = others
            .iter()
            .skip(1)
            .filter(|&&i| {
                let d = [c[i][0] - c[seed][0], c[i][1] - c[seed][1]];
                let l = dist(&c[i], &c[seed]);
                ((d[0] * d1[0] + d[1] * d1[1]) / (l * l1)).abs() < 0.9 && l < 3.0 * l1
            })
            .take(3)
            .cloned()
            .collect();
        for n2 in second {
            out.push((seed, n1, n2));
        }
    }
    out
}

/// Grows a lattice from a seed triple; returns (a, b) → candidate index.
fn grow_grid(c: &[[f64; 2]], (seed, n1, n2): (usize, usize, usize)) -> HashMap<(i32, i32), usize> {
    let d1 = [c[n1][0] - c[seed][0], c[n1][1] - c[seed][1]];
    let d2 = [c[n2][0] - c[seed][0], c[n2][1] - c[seed][1]];
    let mut grid: HashMap<(i32, i32), usize> = HashMap::new();
    let mut used = vec![false; c.len()];
    for (k, i) in [((0, 0), seed), ((1, 0), n1), ((0, 1), n2)] {
        grid.insert(k, i);
        used[i] = true;
    }
    loop {
        let mut added = false;
        let keys: Vec<(i32, i32)> = grid.keys().cloned().collect();
        for (a, b) in keys {
            for (da, db) in [(1, 0), (-1, 0), (0, 1), (0, -1)] {
                let target = (a + da, b + db);
                if grid.contains_key(&target) {
                    continue;
                }
                let p = c[grid[&(a, b)]];
                let step = if let Some(&q) = grid.get(&(a - da, b - db)) {
                    Some([p[0] - c[q][0], p[1] - c[q][1]])
                } else {
                    let perp = (db, da);
                    [1, -1, 2, -2].iter().find_map(|&k| {
                        let s0 = grid.get(&(a + k * perp.0, b + k * perp.1))?;
                        let s1 = grid.get(&(a + k * perp.0 + da, b + k * perp.1 + db))?;
                        Some([c[*s1][0] - c[*s0][0], c[*s1][1] - c[*s0][1]])
                    })
                };
                let step = step.unwrap_or_else(|| {
                    let d = if da != 0 { d1 } else { d2 };
                    let s = (da + db) as f64;
                    [s * d[0], s * d[1]]
                });
                let pred = [p[0] + step[0], p[1] + step[1]];
                let tol = 0.3 * (step[0].hypot(step[1]));
                let best = (0..c.len())
                    .filter(|&i| !used[i])
                    .min_by(|&i, &j| dist(&c[i], &pred).total_cmp(&dist(&c[j], &pred)));
                if let Some(i) = best {
                    if dist(&c[i], &pred) < tol {
                        grid.insert(target, i);
                        used[i] = true;
                        added = true;
                    }
                }
            }
        }
        if !added {
            break;
        }
    }
    grid
}

/// Sub-pixel corner position: iterates q ← (Σ w g gᵀ)⁻¹ Σ w g gᵀ p over a Gaussian-weighted
/// window of radius `radius` around q, g the image gradient at pixel p.
fn refine_corner(
    gx: &[f32],
    gy: &[f32],
    w: usize,
    h: usize,
    q0: [f64; 2],
    radius: f64,
) -> Option<[f64; 2]> {
    let mut q = q0;
    let r = radius.ceil() as isize;
    let sig2 = (0.5 * radius).powi(2);
    for _ in 0..30 {
        let (cx, cy) = (q[0].round() as isize, q[1].round() as isize);
        let (mut a11, mut a12, mut a22, mut b1, mut b2) = (0.0, 0.0, 0.0, 0.0, 0.0);
        for y in cy - r..=cy + r {
            for x in cx - r..=cx + r {
                if x < 1 || y < 1 || x >= w as isize - 1 || y >= h as isize - 1 {
                    continue;
                }
                let (dx, dy) = (x as f64 - q[0], y as f64 - q[1]);
                let d2 = dx * dx + dy * dy;
                if d2 > radius * radius {
                    continue;
                }
                let wt = (-d2 / (2.0 * sig2)).exp();
                let i = y as usize * w + x as usize;
                let (u, v) = (gx[i] as f64, gy[i] as f64);
                let (guu, guv, gvv) = (wt * u * u, wt * u * v, wt * v * v);
                a11 += guu;
                a12 += guv;
                a22 += gvv;
                b1 += guu * x as f64 + guv * y as f64;
                b2 += guv * x as f64 + gvv * y as f64;
            }
        }
        let det = a11 * a22 - a12 * a12;
        if !(det.abs() > 1e-12 * (a11 + a22).powi(2)) || !det.is_finite() {
            return None;
        }
        let nq = [(a22 * b1 - a12 * b2) / det, (a11 * b2 - a12 * b1) / det];
        let shift = dist(&nq, &q);
        q = nq;
        if dist(&q, &q0) > radius {
            return None;
        }
        if shift < 1e-4 {
            break;
        }
    }
    Some(q)
}

/// Sub-pixel saddle point: Newton iteration on the gradient of the image smoothed by a
/// Gaussian of `sigma`, the smoothing evaluated exactly at the current position.
fn refine_saddle(img: &GrayImage, q0: [f64; 2], sigma: f64, max_shift: f64) -> Option<[f64; 2]> {
    let (w, h) = (img.width as isize, img.height as isize);
    let r = (3.5 * sigma).ceil() as isize;
    let s2 = sigma * sigma;
    let mut q = q0;
    for _ in 0..30 {
        let (cx, cy) = (q[0].round() as isize, q[1].round() as isize);
        if cx - r < 0 || cy - r < 0 || cx + r >= w || cy + r >= h {
            return None;
        }
        let mut mean = 0.0;
        let mut cnt = 0.0;
        for y in cy - r..=cy + r {
            for x in cx - r..=cx + r {
                mean += img.at(x as usize, y as usize) as f64;
                cnt += 1.0;
            }
        }
        mean /= cnt;
        let (mut gx, mut gy, mut hxx, mut hxy, mut hyy) = (0.0, 0.0, 0.0, 0.0, 0.0);
        for y in cy - r..=cy + r {
            for x in cx - r..=cx + r {
                let dx = q[0] - x as f64;
                let dy = q[1] - y as f64;
                let g = (-(dx * dx + dy * dy) / (2.0 * s2)).exp();
                let v = (img.at(x as usize, y as usize) as f64 - mean) * g;
                gx -= v * dx / s2;
                gy -= v * dy / s2;
                hxx += v * (dx * dx / (s2 * s2) - 1.0 / s2);
                hyy += v * (dy * dy / (s2 * s2) - 1.0 / s2);
                hxy += v * dx * dy / (s2 * s2);
            }
        }
        let det = hxx * hyy - hxy * hxy;
        if !(det < 0.0) || !det.is_finite() {
            return None;
        }
        let sx = (hyy * gx - hxy * gy) / det;
        let sy = (hxx * gy - hxy * gx) / det;
        let mut step = [-sx, -sy];
        let len = step[0].hypot(step[1]);
        if len > 0.5 * sigma {
            step = [step[0] * 0.5 * sigma / len, step[1] * 0.5 * sigma / len];
        }
        q = [q[0] + step[0], q[1] + step[1]];
        if dist(&q, &q0) > max_shift {
            return None;
        }
        if len < 1e-5 {
            break;
        }
    }
    Some(q)
}

/// Finds the inner corners of `board` in a target frame, in [`BoardGeometry::inner_corners`]
/// order, with sub-pixel accuracy. `image` is the index reported in errors.
///
/// The labelling is fixed by the board's handedness (the image directions of the target x and
/// y axes have a positive cross product, as for a board seen from its front) and, when the colour pattern is not symmetric under a half turn, by the square
/// colours (square (i, j) black when i + j is even); for half-turn symmetric boards the
/// labelling with corner (1, 1) nearest the image origin is chosen.
pub fn detect_board(
    frame: &BayerFrame,
    board: &BoardGeometry,
    opts: &CornerOptions,
    image: usize,
) -> CalibResult<Vec<[f64; 2]>> {
    detect_board_flat(frame, None, board, opts, image)
}

/// [`detect_board`] in `frame` flat-fielded by `flat` (when given): each photosite divided by
/// its gain, in floating point.
pub fn detect_board_flat(
    frame: &BayerFrame,
    flat: Option<&FlatField>,
    board: &BoardGeometry,
    opts: &CornerOptions,
    image: usize,
) -> CalibResult<Vec<[f64; 2]>> {
    board.validate()?;
    let not_found = |reason: String| CalibError::BoardNotFound { image, reason };
    let green = match opts.image {
        CornerImage::Balanced => balanced_image(frame, flat)?,
        CornerImage::Green => green_image(frame, flat)?,
    };
    let smooth = gaussian_blur(&green, opts.detect_sigma_px);
    let (cx, cy) = (board.corners_x(), board.corners_y());
    let expected = cx * cy;
    let cand = candidates(&smooth, opts, 6 * expected + 20);
    if cand.len() < expected {
        return Err(not_found(format!(
            "{} X-junctions found, {expected} expected",
            cand.len()
        )));
    }
    let mut found = None;
    let mut last = String::from("no lattice of corners");
    for seed in lattice_seeds(&cand) {
        let grid = grow_grid(&cand, seed);
        let amin = grid.keys().map(|k| k.0).min().unwrap_or(0);
        let amax = grid.keys().map(|k| k.0).max().unwrap_or(0);
        let bmin = grid.keys().map(|k| k.1).min().unwrap_or(0);
        let bmax = grid.keys().map(|k| k.1).max().unwrap_or(0);
        let (na, nb) = ((amax - amin + 1) as usize, (bmax - bmin + 1) as usize);
        if grid.len() == na * nb && ((na == cx && nb == cy) || (na == cy && nb == cx)) {
            found = Some((grid, amin, bmin, na, nb));
            break;
        }
        last = format!(
            "lattice of {} corners spanning {na}x{nb}, board has {cx}x{cy}",
            grid.len()
        );
    }
    let (grid, amin, bmin, na, nb) = found.ok_or_else(|| not_found(last))?;
    let at = |a: i32, b: i32| cand[grid[&(a, b)]];
    // Candidate labellings: board (i, j) (1-based inner-corner indices) → lattice (a, b).
    type Label = Box<dyn Fn(usize, usize) -> (i32, i32)>;
    let mut labellings: Vec<Label> = Vec::new();
    for swap in [false, true] {
        let (la, lb) = if swap { (nb, na) } else { (na, nb) };
        if la != cx || lb != cy {
            continue;
        }
        for (fa, fb) in [(false, false), (true, false), (false, true), (true, true)] {
            labellings.push(Box::new(move |i: usize, j: usize| {
                let (p, q) = (i as i32 - 1, j as i32 - 1);
                let p = if fa { cx as i32 - 1 - p } else { p };
                let q = if fb { cy as i32 - 1 - q } else { q };
                if swap {
                    (amin + q, bmin + p)
                } else {
                    (amin + p, bmin + q)
                }
            }));
        }
    }
    let corner = |l: &Label, i: usize, j: usize| {
        let (a, b) = l(i, j);
        at(a, b)
    };
    let mut best: Option<(f64, f64, usize)> = None;
    for (li, l) in labellings.iter().enumerate() {
        // Handedness: image cross product of the board x and y directions must be positive.
        let p0 = corner(l, 1, 1);
        let px = corner(l, cx, 1);
        let py = corner(l, 1, cy);
        let cross = (px[0] - p0[0]) * (py[1] - p0[1]) - (px[1] - p0[1]) * (py[0] - p0[0]);
        if cross <= 0.0 {
            continue;
        }
        // Colour score over inner squares.
        let mut score = 0.0;
        for j in 1..cy {
            for i in 1..cx {
                let q = [
                    corner(l, i, j),
                    corner(l, i + 1, j),
                    corner(l, i, j + 1),
                    corner(l, i + 1, j + 1),
                ];
                let m = [
                    0.25 * q.iter().map(|p| p[0]).sum::<f64>(),
                    0.25 * q.iter().map(|p| p[1]).sum::<f64>(),
                ];
                let v = smooth.sample(m[0], m[1]);
                score += if (i + j) % 2 == 0 { -v } else { v };
            }
        }
        let origin_dist = p0[0].hypot(p0[1]);
        let better = match best {
            None => true,
            Some((s, d, _)) => {
                let tol = 1e-6 * s.abs().max(1.0);
                score > s + tol || ((score - s).abs() <= tol && origin_dist < d)
            }
        };
        if better {
            best = Some((score, origin_dist, li));
        }
    }
    let (score, _, li) = best.ok_or_else(|| not_found("no consistent labelling".into()))?;
    if !(score > 0.0) {
        return Err(not_found("square colours do not match the board".into()));
    }
    let label = &labellings[li];
    // Sub-pixel refinement.
    let (w, h) = (green.width, green.height);
    let (mut gx, mut gy) = (Vec::new(), Vec::new());
    if opts.subpixel == SubpixelMethod::GradientOrthogonality {
        let rimg = gaussian_blur(&green, opts.refine_sigma_px);
        gx = vec![0f32; w * h];
        gy = vec![0f32; w * h];
        for y in 1..h - 1 {
            for x in 1..w - 1 {
                gx[y * w + x] = 0.5 * (rimg.at(x + 1, y) - rimg.at(x - 1, y));
                gy[y * w + x] = 0.5 * (rimg.at(x, y + 1) - rimg.at(x, y - 1));
            }
        }
    }
    let mut out = Vec::with_capacity(expected);
    for j in 1..=cy {
        for i in 1..=cx {
            let (a, b) = label(i, j);
            let p = at(a, b);
            let local = [(1, 0), (-1, 0), (0, 1), (0, -1)]
                .iter()
                .filter_map(|(da, db)| grid.get(&(a + da, b + db)).map(|&k| dist(&cand[k], &p)))
                .fold(f64::INFINITY, f64::min);
            let radius = (opts.window_fraction * local).clamp(2.5, 40.0);
            let q = match opts.subpixel {
                SubpixelMethod::GradientOrthogonality => refine_corner(&gx, &gy, w, h, p, radius),
                SubpixelMethod::Saddle => {
                    // Keep the kernel (3.5 σ) inside the image near its border.
                    let border = p[0]
                        .min(p[1])
                        .min(w as f64 - 1.0 - p[0])
                        .min(h as f64 - 1.0 - p[1]);
                    let sigma = (opts.saddle_fraction * local)
                        .min(opts.max_saddle_sigma_px)
                        .min((border - 2.0) / 3.5)
                        .clamp(0.8, 0.25 * local);
                    refine_saddle(&green, p, sigma, 0.5 * local)
                }
            }
            .ok_or_else(|| {
                not_found(format!("sub-pixel refinement failed at corner ({i}, {j})"))
            })?;
            out.push(q);
        }
    }
    Ok(out)
}
