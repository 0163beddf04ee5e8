//! Checkerboard inner-corner detection in raw Bayer frames: colour-balanced (or green-channel)
//! image, saddle-point response (negative Hessian determinant), ring test for X-junctions, grid growing and
//! labelling, sub-pixel refinement by the gradient-orthogonality condition.

use crate::board::BoardGeometry;
use crate::error::{CalibError, CalibResult};
use crate::frames::FlatField;
use crate::lattice;
use gantry_hal::BayerFrame;
use serde::{Deserialize, Serialize};

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
    /// The luminance of a decoded image file (PNG, JPEG, TIFF; 8 or 16 bit; grey or colour),
    /// scaled to [0, 1].
    pub fn from_dynamic(img: &image::DynamicImage) -> Self {
        let l = img.to_luma32f();
        Self {
            width: l.width() as usize,
            height: l.height() as usize,
            data: l.into_raw(),
        }
    }

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
    /// X-junction candidates whose ring contrast is below this fraction of the image's
    /// 5–95 % range are ignored (low for uneven lighting and vignetting).
    #[serde(default = "default_min_contrast_fraction")]
    pub min_contrast_fraction: f64,
    /// Seed candidates tried for growing the lattice (strongest first).
    #[serde(default = "default_max_seeds")]
    pub max_seeds: usize,
}

fn default_min_contrast_fraction() -> f64 {
    0.1
}

fn default_max_seeds() -> usize {
    40
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
            response_fraction: 0.01,
            subpixel: SubpixelMethod::Saddle,
            saddle_fraction: 0.25,
            max_saddle_sigma_px: 12.0,
            image: CornerImage::Balanced,
            min_contrast_fraction: default_min_contrast_fraction(),
            max_seeds: default_max_seeds(),
        }
    }
}

fn dist(a: &[f64; 2], b: &[f64; 2]) -> f64 {
    lattice::dist(a, b)
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
        // The Gaussian is separable: per-column weights once, then row sums.
        let n = (2 * r + 1) as usize;
        let mut ax = vec![0f64; n];
        for (i, a) in ax.iter_mut().enumerate() {
            let dx = q[0] - (cx - r + i as isize) as f64;
            *a = (-(dx * dx) / (2.0 * s2)).exp();
        }
        let (mut gx, mut gy, mut hxx, mut hxy, mut hyy) = (0.0, 0.0, 0.0, 0.0, 0.0);
        for y in cy - r..=cy + r {
            let dy = q[1] - y as f64;
            let by = (-(dy * dy) / (2.0 * s2)).exp();
            let row = &img.data[y as usize * img.width + (cx - r) as usize..][..n];
            let (mut r0, mut r1, mut r2) = (0.0, 0.0, 0.0);
            for (i, (&v, &a)) in row.iter().zip(ax.iter()).enumerate() {
                let dx = q[0] - (cx - r + i as isize) as f64;
                let va = (v as f64 - mean) * a;
                r0 += va;
                r1 += va * dx;
                r2 += va * dx * dx;
            }
            gx -= by * r1 / s2;
            gy -= by * dy * r0 / s2;
            hxx += by * (r2 / (s2 * s2) - r0 / s2);
            hyy += by * r0 * (dy * dy / (s2 * s2) - 1.0 / s2);
            hxy += by * dy * r1 / (s2 * s2);
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
///
/// # How corners are found
///
/// Every candidate is a local maximum of the saddle response that passes a ring test: on a
/// circle around it the image alternates dark/bright/dark/bright, and the four transitions lie
/// on two straight lines through the centre (the two square edges crossing there). The lattice
/// is grown from a seed candidate along those lines; a neighbour is accepted only when the
/// segment joining it to its parent is a square edge: the image on its two sides differs by a
/// good part of the local contrast. Corners that gave no candidate (low contrast, blur) are
/// looked for at their predicted position.
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
    let green = match opts.image {
        CornerImage::Balanced => balanced_image(frame, flat)?,
        CornerImage::Green => green_image(frame, flat)?,
    };
    detect_board_gray(&green, board, opts, image)
}

/// [`detect_board`] in a single-channel image (a photograph: [`GrayImage::from_dynamic`]).
pub fn detect_board_gray(
    green: &GrayImage,
    board: &BoardGeometry,
    opts: &CornerOptions,
    image: usize,
) -> CalibResult<Vec<[f64; 2]>> {
    board.validate()?;
    let not_found = |reason: String| CalibError::BoardNotFound { image, reason };
    let smooth = gaussian_blur(green, opts.detect_sigma_px);
    let (cx, cy) = (board.corners_x(), board.corners_y());
    let expected = cx * cy;
    let rho = (3.0 * opts.detect_sigma_px).max(4.0);
    let nms = (2.0 * opts.detect_sigma_px).ceil().max(2.0) as usize;
    let cand = lattice::candidates(
        &smooth,
        nms,
        rho,
        opts.response_fraction,
        opts.min_contrast_fraction,
        8 * expected + 200,
    );
    if cand.len() < 3 {
        return Err(not_found(format!(
            "{} X-junctions found, {expected} expected",
            cand.len()
        )));
    }
    let relocate = |q: [f64; 2], tol: f64| {
        let sigma = (0.5 * tol).clamp(1.0, 4.0);
        refine_saddle(green, q, sigma, tol)
    };
    let grower = lattice::Grower {
        smooth: &smooth,
        rho,
        cand: &cand,
        max_nodes: 4 * expected + 16,
        relocate: &relocate,
    };
    let mut found = None;
    let mut last = String::from("no lattice of corners");
    let mut covered = vec![false; cand.len()];
    let mut tried = 0;
    let mut largest = 0;
    for seed in 0..cand.len() {
        if covered[seed] {
            continue;
        }
        if tried >= opts.max_seeds {
            break;
        }
        tried += 1;
        let Some(grid) = grower.grow(seed) else {
            continue;
        };
        for (k, c) in cand.iter().enumerate() {
            if grid.values().any(|q| lattice::dist(q, &c.p) < 1.0) {
                covered[k] = true;
            }
        }
        largest = largest.max(grid.len());
        let windows = lattice::complete_windows(&grid, cx, cy);
        if windows.len() == 1 {
            let (a0, b0, t) = windows[0];
            let (na, nb) = if t { (cy, cx) } else { (cx, cy) };
            found = Some((grid, a0, b0, na, nb));
            break;
        }
        if grid.len() > 3 {
            last = format!(
                "lattice of {} corners holds {} complete {cx}x{cy} windows",
                grid.len(),
                windows.len()
            );
        }
    }
    let Some((grid, amin, bmin, na, nb)) = found else {
        return Err(if 3 * largest >= expected && largest < expected {
            CalibError::TooFewCorners {
                image,
                found: largest,
                expected,
                reason: last,
            }
        } else {
            not_found(last)
        });
    };
    let at = |a: i32, b: i32| grid[&(a, b)];
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
        let rimg = gaussian_blur(green, opts.refine_sigma_px);
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
                .filter_map(|(da, db)| grid.get(&(a + da, b + db)).map(|q| dist(q, &p)))
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
                    refine_saddle(green, p, sigma, 0.5 * local)
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
