//! Calibration scenes: a checkerboard target in chosen poses (for intrinsic calibration after
//! Zhang) and a contact digitizer that returns noisy 3D points (digitizer tip, lamp positions,
//! sphere surface), as in the thesis's section 3.2.

use crate::scene::Scene;
use crate::truth::{Point3, SceneTruth};
use crate::SimError;
use gantry_hal::BayerFrame;
use nalgebra::{Rotation3, Vector3};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rayon::prelude::*;
use serde::{Deserialize, Serialize};

/// A planar checkerboard target on a white border, lit uniformly.
///
/// Target frame: the board lies in z = 0 and covers [0, nx·s] × [0, ny·s]; square (i, j) (column
/// i, row j) is black when i + j is even. Inner corners are at (i·s, j·s), i = 1..nx−1,
/// j = 1..ny−1.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Checkerboard {
    /// Squares along x.
    pub squares_x: usize,
    /// Squares along y.
    pub squares_y: usize,
    /// Square side, metres.
    pub square_m: f64,
    /// Width of the white border around the squares, metres.
    pub border_m: f64,
    /// Diffuse reflectance of the white squares.
    pub white: f64,
    /// Diffuse reflectance of the black squares.
    pub black: f64,
    /// Uniform irradiance on the target, W/m².
    pub irradiance: f64,
}

impl Default for Checkerboard {
    fn default() -> Self {
        Self {
            squares_x: 9,
            squares_y: 7,
            square_m: 0.008,
            border_m: 0.006,
            white: 0.8,
            black: 0.05,
            irradiance: 5.0,
        }
    }
}

impl Checkerboard {
    /// Inner corners in target coordinates, row-major (y outer).
    pub fn inner_corners(&self) -> Vec<Point3> {
        let s = self.square_m;
        (1..self.squares_y)
            .flat_map(|j| (1..self.squares_x).map(move |i| [i as f64 * s, j as f64 * s, 0.0]))
            .collect()
    }

    /// Reflectance at target coordinates (x, y); `None` outside the target.
    pub fn reflectance(&self, x: f64, y: f64) -> Option<f64> {
        let (w, h) = (
            self.squares_x as f64 * self.square_m,
            self.squares_y as f64 * self.square_m,
        );
        let b = self.border_m;
        if x < -b || y < -b || x > w + b || y > h + b {
            return None;
        }
        if x < 0.0 || y < 0.0 || x >= w || y >= h {
            return Some(self.white);
        }
        let i = (x / self.square_m).floor() as i64;
        let j = (y / self.square_m).floor() as i64;
        Some(if (i + j) % 2 == 0 {
            self.black
        } else {
            self.white
        })
    }

    /// Centre of the squares in target coordinates.
    pub fn centre(&self) -> Point3 {
        [
            0.5 * self.squares_x as f64 * self.square_m,
            0.5 * self.squares_y as f64 * self.square_m,
            0.0,
        ]
    }
}

/// Pose of the target relative to the camera: p_cam = R(rotation)·p_target + translation, with
/// `rotation` an axis-angle vector (radians).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct TargetPose {
    /// Axis-angle rotation vector, radians.
    pub rotation: Point3,
    /// Translation, metres.
    pub translation: Point3,
}

impl TargetPose {
    /// Rotation matrix of the pose.
    pub fn rotation_matrix(&self) -> Rotation3<f64> {
        Rotation3::new(Vector3::from(self.rotation))
    }

    /// Target point to camera coordinates.
    pub fn to_camera(&self, p: &Point3) -> Vector3<f64> {
        self.rotation_matrix() * Vector3::from(*p) + Vector3::from(self.translation)
    }

    /// A pose that puts the centre of `board` on the optical axis at `distance` metres, offset by
    /// (`dx`, `dy`) metres, after tilting by `tilt_x`, `tilt_y` radians about the camera axes.
    pub fn facing(
        board: &Checkerboard,
        distance: f64,
        tilt_x: f64,
        tilt_y: f64,
        dx: f64,
        dy: f64,
    ) -> Self {
        let r = Rotation3::from_axis_angle(&Vector3::x_axis(), tilt_x)
            * Rotation3::from_axis_angle(&Vector3::y_axis(), tilt_y);
        let c = r * Vector3::from(board.centre());
        let t = Vector3::new(dx, dy, distance) - c;
        let rv = r.scaled_axis();
        Self {
            rotation: [rv.x, rv.y, rv.z],
            translation: [t.x, t.y, t.z],
        }
    }

    /// `n` varied poses (tilts up to ±35°, small offsets) at about `distance` metres, seeded.
    pub fn varied(board: &Checkerboard, n: usize, distance: f64, seed: u64) -> Vec<Self> {
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        (0..n)
            .map(|_| {
                let tx = rng.gen_range(-0.6..0.6);
                let ty = rng.gen_range(-0.6..0.6);
                let d = distance * rng.gen_range(0.93..1.07);
                let off = 0.004;
                Self::facing(
                    board,
                    d,
                    tx,
                    ty,
                    rng.gen_range(-off..off),
                    rng.gen_range(-off..off),
                )
            })
            .collect()
    }
}

/// A captured checkerboard frame with its ground truth.
#[derive(Debug, Clone, PartialEq)]
pub struct CheckerboardCapture {
    /// The raw frame.
    pub frame: BayerFrame,
    /// True pixel positions of the inner corners (with distortion), same order as
    /// [`Checkerboard::inner_corners`]; `None` for corners behind the camera.
    pub corners_px: Vec<Option<[f64; 2]>>,
    /// The pose used.
    pub pose: TargetPose,
}

/// Supersampling per pixel axis, used only for pixels whose footprint on the target cannot be
/// found (a corner ray misses the target's plane).
const SUPERSAMPLE: usize = 4;

/// Point of the target plane (target coordinates x, y) seen along the camera ray `d`; `None` if
/// the ray is parallel to the plane or meets it behind the camera.
fn target_point(
    r_inv: &Rotation3<f64>,
    n: &Vector3<f64>,
    nt: f64,
    tr: &Vector3<f64>,
    d: &Vector3<f64>,
) -> Option<[f64; 2]> {
    let dn = n.dot(d);
    if dn.abs() < 1e-12 {
        return None;
    }
    let s = nt / dn;
    if s <= 0.0 {
        return None;
    }
    let q = r_inv * (s * d - tr);
    Some([q.x, q.y])
}

/// Signed area of a polygon (shoelace).
fn polygon_area(p: &[[f64; 2]]) -> f64 {
    let n = p.len();
    let mut a = 0.0;
    for i in 0..n {
        let (u, v) = (p[i], p[(i + 1) % n]);
        a += u[0] * v[1] - v[0] * u[1];
    }
    0.5 * a
}

/// Clips a polygon to the half-plane `sign·(coordinate axis) ≤ sign·limit` (Sutherland–Hodgman).
fn clip_half_plane(p: &[[f64; 2]], axis: usize, limit: f64, sign: f64) -> Vec<[f64; 2]> {
    let inside = |q: &[f64; 2]| sign * (q[axis] - limit) <= 0.0;
    let mut out = Vec::with_capacity(p.len() + 2);
    for i in 0..p.len() {
        let (a, b) = (p[i], p[(i + 1) % p.len()]);
        let (ia, ib) = (inside(&a), inside(&b));
        if ia {
            out.push(a);
        }
        if ia != ib {
            let t = (limit - a[axis]) / (b[axis] - a[axis]);
            out.push([a[0] + t * (b[0] - a[0]), a[1] + t * (b[1] - a[1])]);
        }
    }
    out
}

/// Area of the convex polygon `p` inside the rectangle [x0, x1] × [y0, y1].
fn area_in_rect(p: &[[f64; 2]], x0: f64, x1: f64, y0: f64, y1: f64) -> f64 {
    let mut q = clip_half_plane(p, 0, x0, -1.0);
    for (axis, limit, sign) in [(0, x1, 1.0), (1, y0, -1.0), (1, y1, 1.0)] {
        if q.len() < 3 {
            return 0.0;
        }
        q = clip_half_plane(&q, axis, limit, sign);
    }
    if q.len() < 3 {
        0.0
    } else {
        polygon_area(&q).abs()
    }
}

/// Sorted positions, inside (lo, hi), where the target's reflectance may change along one axis:
/// the square lines, the edges of the squares' field and of the border.
fn breakpoints(lo: f64, hi: f64, square: f64, extent: f64, border: f64) -> Vec<f64> {
    let mut b = vec![lo];
    let mut k = (lo / square).floor() as i64 + 1;
    while (k as f64) * square < hi {
        let x = k as f64 * square;
        if x > -border && x < extent + border {
            b.push(x);
        }
        k += 1;
    }
    for e in [-border, extent + border] {
        if e > lo && e < hi {
            b.push(e);
        }
    }
    b.push(hi);
    b.sort_by(f64::total_cmp);
    b
}

/// Mean reflectance (0 outside the target) over the quadrilateral `quad` of target coordinates:
/// the exact area average, the quadrilateral being cut along every line where the pattern
/// changes.
fn mean_reflectance(board: &Checkerboard, quad: &[[f64; 2]; 4]) -> f64 {
    let total = polygon_area(quad).abs();
    if total <= 0.0 {
        return board.reflectance(quad[0][0], quad[0][1]).unwrap_or(0.0);
    }
    let (mut x0, mut x1, mut y0, mut y1) = (
        f64::INFINITY,
        f64::NEG_INFINITY,
        f64::INFINITY,
        f64::NEG_INFINITY,
    );
    for q in quad {
        x0 = x0.min(q[0]);
        x1 = x1.max(q[0]);
        y0 = y0.min(q[1]);
        y1 = y1.max(q[1]);
    }
    let w = board.squares_x as f64 * board.square_m;
    let h = board.squares_y as f64 * board.square_m;
    let xs = breakpoints(x0, x1, board.square_m, w, board.border_m);
    let ys = breakpoints(y0, y1, board.square_m, h, board.border_m);
    if xs.len() == 2 && ys.len() == 2 {
        // One piece: the footprint does not cross a line of the pattern.
        return board
            .reflectance(0.5 * (x0 + x1), 0.5 * (y0 + y1))
            .unwrap_or(0.0);
    }
    let mut acc = 0.0;
    for xw in xs.windows(2) {
        for yw in ys.windows(2) {
            let rho = board
                .reflectance(0.5 * (xw[0] + xw[1]), 0.5 * (yw[0] + yw[1]))
                .unwrap_or(0.0);
            if rho != 0.0 {
                acc += rho * area_in_rect(quad, xw[0], xw[1], yw[0], yw[1]);
            }
        }
    }
    acc / total
}

/// Renders the target's radiance image: each pixel is the exact average of the target's
/// radiance over the pixel's footprint (the quadrilateral of the target plane seen by its four
/// corners; the camera map is affine to ~1e-8 within one pixel), plus the room's stray light.
pub(crate) fn render_checkerboard(
    scene: &Scene,
    board: &Checkerboard,
    pose: &TargetPose,
) -> Vec<[f32; 3]> {
    let t = scene.truth();
    let cam = t.camera;
    let r = pose.rotation_matrix();
    let r_inv = r.inverse();
    let tr = Vector3::from(pose.translation);
    let n = r * Vector3::z();
    let nt = n.dot(&tr);
    let stray = t.stray_radiance.map(|x| x as f32);
    let (w, h) = (cam.width, cam.height);
    let radiance = board.irradiance / std::f64::consts::PI;
    // Target points seen by the pixel corners (u, v) = (i − ½, j − ½), i ≤ w, j ≤ h.
    let corner_row = |j: usize| -> Vec<Option<[f64; 2]>> {
        (0..=w)
            .map(|i| {
                let d = cam.ray(i as f64 - 0.5, j as f64 - 0.5);
                target_point(&r_inv, &n, nt, &tr, &d)
            })
            .collect()
    };
    let corners: Vec<Vec<Option<[f64; 2]>>> = (0..=h).into_par_iter().map(corner_row).collect();
    let mut rgb = vec![[0f32; 3]; w * h];
    rgb.par_chunks_mut(w).enumerate().for_each(|(y, row)| {
        for (x, o) in row.iter_mut().enumerate() {
            let quad = [
                corners[y][x],
                corners[y][x + 1],
                corners[y + 1][x + 1],
                corners[y + 1][x],
            ];
            let mean = if let [Some(a), Some(b), Some(c), Some(d)] = quad {
                mean_reflectance(board, &[a, b, c, d])
            } else {
                // The pixel sees the horizon of the target plane: point-sample it.
                let mut acc = 0.0;
                for sy in 0..SUPERSAMPLE {
                    for sx in 0..SUPERSAMPLE {
                        let u = x as f64 - 0.5 + (sx as f64 + 0.5) / SUPERSAMPLE as f64;
                        let v = y as f64 - 0.5 + (sy as f64 + 0.5) / SUPERSAMPLE as f64;
                        if let Some(q) = target_point(&r_inv, &n, nt, &tr, &cam.ray(u, v)) {
                            acc += board.reflectance(q[0], q[1]).unwrap_or(0.0);
                        }
                    }
                }
                acc / (SUPERSAMPLE * SUPERSAMPLE) as f64
            };
            // Lambertian target: L = ρ E / π.
            let l = (mean * radiance) as f32;
            *o = [l + stray[0], l + stray[1], l + stray[2]];
        }
    });
    rgb
}

/// Checks a checkerboard's geometry.
pub(crate) fn check_board(board: &Checkerboard) -> Result<(), SimError> {
    if board.squares_x < 2
        || board.squares_y < 2
        || !(board.square_m > 0.0 && board.square_m.is_finite())
        || !(board.border_m >= 0.0 && board.border_m.is_finite())
    {
        return Err(SimError::Config(
            "checkerboard needs ≥ 2 × 2 squares of positive size and a finite border".into(),
        ));
    }
    Ok(())
}

/// True pixel positions of the board's inner corners at `pose`.
pub(crate) fn true_corners(
    scene: &Scene,
    board: &Checkerboard,
    pose: &TargetPose,
) -> Vec<Option<[f64; 2]>> {
    let cam = scene.truth().camera;
    board
        .inner_corners()
        .iter()
        .map(|p| cam.project_camera_point(&pose.to_camera(p)))
        .collect()
}

/// Exposes the sensor to the radiance image `rgb` (no lamp, no sample) for `exposure_s`.
pub(crate) fn expose_radiance(
    scene: &Scene,
    rgb: &[[f32; 3]],
    exposure_s: f64,
    timestamp_s: f64,
    frame_number: u64,
) -> Result<BayerFrame, SimError> {
    let t = scene.truth();
    let (w, h) = (t.camera.width, t.camera.height);
    let rate = scene.light_rate_e(&scene.mosaic(rgb));
    let zeros = vec![0f32; w * h];
    let temp = t.sensor.temperature_c;
    let samples = scene.expose(&rate, 1.0, &zeros, exposure_s, temp, frame_number)?;
    Ok(BayerFrame::new(
        w,
        h,
        t.sensor.bit_depth,
        scene.pattern(),
        samples,
        exposure_s,
        timestamp_s,
        temp,
        frame_number,
    )?)
}

/// One digitizer-tip correspondence for the camera's external calibration.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct TipObservation {
    /// Tip position as the digitizer reports it (world frame, with noise), metres.
    pub measured: Point3,
    /// Tip position in the image as located by the operator (with noise), pixels.
    pub pixel: [f64; 2],
    /// True tip position, metres.
    pub true_point: Point3,
}

/// A contact digitizer (FARO-arm-like) measuring in the world frame with isotropic Gaussian
/// noise: the operator's instrument of thesis §3.2 for the lamp positions, the sphere and the
/// camera pose.
///
/// # Examples
///
/// Digitized lamp positions lie on the true lamp circle up to the instrument's noise:
///
/// ```
/// use hal_sim::{SimConfig, SimRig};
/// use nalgebra::Vector3;
/// use std::sync::Arc;
///
/// let sim = SimRig::new(SimConfig::with_scale(0.1), Arc::new(brdf::load("lambert:kd=0.5").unwrap()))
///     .unwrap();
/// let circle = sim.truth().lamp.circle;
/// let mut digitizer = sim.digitizer(1e-4, 7); // 0.1 mm noise
/// for (angle, p) in [0.0, 90.0, 180.0].iter().zip(digitizer.lamp_positions(&[0.0, 90.0, 180.0])) {
///     let off = (Vector3::from(p) - circle.position(*angle)).norm();
///     assert!(off < 1e-3, "{angle}: {off}");
/// }
/// ```
#[derive(Debug, Clone)]
pub struct ContactDigitizer {
    truth: SceneTruth,
    sigma: f64,
    rng: ChaCha8Rng,
}

impl ContactDigitizer {
    /// A digitizer for the scene `truth` with noise `sigma_m` metres, seeded.
    pub fn new(truth: SceneTruth, sigma_m: f64, seed: u64) -> Self {
        Self {
            truth,
            sigma: sigma_m.max(0.0),
            rng: ChaCha8Rng::seed_from_u64(seed),
        }
    }

    fn gauss(&mut self) -> f64 {
        let u1: f64 = self.rng.gen_range(f64::MIN_POSITIVE..1.0);
        let u2: f64 = self.rng.gen();
        (-2.0 * u1.ln()).sqrt() * (std::f64::consts::TAU * u2).cos()
    }

    /// Reading of the digitizer touching the true point `p`.
    pub fn measure(&mut self, p: Point3) -> Point3 {
        let s = self.sigma;
        [
            p[0] + s * self.gauss(),
            p[1] + s * self.gauss(),
            p[2] + s * self.gauss(),
        ]
    }

    /// Readings of the lamp disc centre with the turntable at each of `angles_deg`.
    pub fn lamp_positions(&mut self, angles_deg: &[f64]) -> Vec<Point3> {
        let circle = self.truth.lamp.circle;
        angles_deg
            .iter()
            .map(|&a| {
                let p = circle.position(a);
                self.measure([p.x, p.y, p.z])
            })
            .collect()
    }

    /// `n` readings of points on the sphere surface, spread over the part reachable from above
    /// and in front (polar angle from +z below 120°).
    pub fn sphere_surface(&mut self, n: usize) -> Vec<Point3> {
        let sp = self.truth.sphere;
        (0..n)
            .map(|_| {
                let z: f64 = self.rng.gen_range(-0.5..1.0);
                let phi: f64 = self.rng.gen_range(0.0..std::f64::consts::TAU);
                let s = (1.0 - z * z).sqrt();
                let p = [
                    sp.centre[0] + sp.radius * s * phi.cos(),
                    sp.centre[1] + sp.radius * s * phi.sin(),
                    sp.centre[2] + sp.radius * z,
                ];
                self.measure(p)
            })
            .collect()
    }

    /// `n` tip positions spread over the image and over ±`depth_m` around the sphere's
    /// distance, each with the digitizer reading and the image position located with
    /// `pixel_sigma` pixels of noise.
    pub fn tip_observations(
        &mut self,
        n: usize,
        depth_m: f64,
        pixel_sigma: f64,
    ) -> Vec<TipObservation> {
        let cam = self.truth.camera;
        let pose = self.truth.pose;
        let centre = pose.centre();
        let dist = (Vector3::from(self.truth.sphere.centre) - centre).norm();
        (0..n)
            .map(|_| {
                let u = self.rng.gen_range(0.05..0.95) * (cam.width - 1) as f64;
                let v = self.rng.gen_range(0.05..0.95) * (cam.height - 1) as f64;
                let depth = dist + self.rng.gen_range(-depth_m..=depth_m);
                let d = pose.dir_to_world(&cam.ray(u, v));
                let p = centre + depth * d;
                let true_point = [p.x, p.y, p.z];
                let measured = self.measure(true_point);
                let pixel = [
                    u + pixel_sigma * self.gauss(),
                    v + pixel_sigma * self.gauss(),
                ];
                TipObservation {
                    measured,
                    pixel,
                    true_point,
                }
            })
            .collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn board() -> Checkerboard {
        Checkerboard {
            squares_x: 4,
            squares_y: 3,
            square_m: 1.0,
            border_m: 0.5,
            white: 0.8,
            black: 0.1,
            irradiance: 1.0,
        }
    }

    /// Mean reflectance over `quad` by point sampling on an n × n grid of the quad's bilinear
    /// parametrisation, weighted by the Jacobian (an independent computation).
    fn sampled_mean(b: &Checkerboard, quad: &[[f64; 2]; 4], n: usize) -> f64 {
        let (mut acc, mut wsum) = (0.0, 0.0);
        for i in 0..n {
            for j in 0..n {
                let (s, t) = ((i as f64 + 0.5) / n as f64, (j as f64 + 0.5) / n as f64);
                let lerp = |k: usize| {
                    (1.0 - s) * (1.0 - t) * quad[0][k]
                        + s * (1.0 - t) * quad[1][k]
                        + s * t * quad[2][k]
                        + (1.0 - s) * t * quad[3][k]
                };
                let d = |k: usize, ds: bool| {
                    if ds {
                        (1.0 - t) * (quad[1][k] - quad[0][k]) + t * (quad[2][k] - quad[3][k])
                    } else {
                        (1.0 - s) * (quad[3][k] - quad[0][k]) + s * (quad[2][k] - quad[1][k])
                    }
                };
                let jac = (d(0, true) * d(1, false) - d(1, true) * d(0, false)).abs();
                acc += jac * b.reflectance(lerp(0), lerp(1)).unwrap_or(0.0);
                wsum += jac;
            }
        }
        acc / wsum
    }

    #[test]
    fn footprint_inside_one_square_sees_its_reflectance() {
        let b = board();
        let q = [[1.2, 0.2], [1.7, 0.3], [1.6, 0.8], [1.1, 0.7]];
        assert_eq!(mean_reflectance(&b, &q), b.white);
        let q = [[0.2, 0.2], [0.7, 0.3], [0.6, 0.8], [0.1, 0.7]];
        assert_eq!(mean_reflectance(&b, &q), b.black);
    }

    #[test]
    fn footprint_across_a_line_is_the_area_weighted_mean() {
        let b = board();
        // Axis-aligned square straddling x = 1 with 0.3 of its width in the black square.
        let q = [[0.7, 0.2], [1.7, 0.2], [1.7, 0.9], [0.7, 0.9]];
        let want = 0.3 * b.black + 0.7 * b.white;
        assert!((mean_reflectance(&b, &q) - want).abs() < 1e-12);
        // Across the outer edge of the border: half of it sees nothing.
        let q = [[-1.0, 1.0], [0.0, 1.0], [0.0, 1.2], [-1.0, 1.2]];
        assert!((mean_reflectance(&b, &q) - 0.5 * b.white).abs() < 1e-12);
    }

    #[test]
    fn exact_coverage_agrees_with_dense_sampling_at_corners() {
        let b = board();
        // Skewed quadrilaterals around X-junctions, the field's corner and the border.
        let quads = [
            [[0.83, 0.91], [1.21, 0.87], [1.18, 1.12], [0.86, 1.19]],
            [[2.6, 1.7], [3.3, 1.95], [3.1, 2.4], [2.7, 2.2]],
            [[-0.3, -0.2], [0.35, -0.1], [0.25, 0.3], [-0.2, 0.4]],
            [[3.8, 2.6], [4.7, 2.8], [4.6, 3.7], [3.7, 3.3]],
        ];
        for q in &quads {
            let exact = mean_reflectance(&b, q);
            let sampled = sampled_mean(&b, q, 1500);
            assert!(
                (exact - sampled).abs() < 2e-3,
                "{q:?}: exact {exact}, sampled {sampled}"
            );
        }
    }
}
