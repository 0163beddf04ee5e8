//! Calibration scenes: a checkerboard target in chosen poses (for intrinsic calibration after
//! Zhang) and a contact digitizer that returns noisy 3D points (digitizer tip, lamp positions,
//! sphere surface), as in the seed's section 3.2.

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

/// Supersampling per pixel axis for anti-aliased square edges.
const SUPERSAMPLE: usize = 4;

pub(crate) fn capture_checkerboard(
    scene: &Scene,
    board: &Checkerboard,
    pose: &TargetPose,
    exposure_s: f64,
    timestamp_s: f64,
    frame_number: u64,
) -> Result<CheckerboardCapture, SimError> {
    let t = scene.truth();
    let cam = t.camera;
    if board.squares_x < 2
        || board.squares_y < 2
        || board.square_m.is_nan()
        || board.square_m <= 0.0
    {
        return Err(SimError::Config(
            "checkerboard needs ≥ 2 × 2 squares of positive size".into(),
        ));
    }
    let r = pose.rotation_matrix();
    let tr = Vector3::from(pose.translation);
    let n = r * Vector3::z();
    let nt = n.dot(&tr);
    let stray = t.stray_radiance.map(|x| x as f32);
    let (w, h) = (cam.width, cam.height);
    let mut rgb = vec![[0f32; 3]; w * h];
    rgb.par_chunks_mut(w).enumerate().for_each(|(y, row)| {
        for (x, o) in row.iter_mut().enumerate() {
            let mut acc = 0.0;
            for sy in 0..SUPERSAMPLE {
                for sx in 0..SUPERSAMPLE {
                    let u = x as f64 - 0.5 + (sx as f64 + 0.5) / SUPERSAMPLE as f64;
                    let v = y as f64 - 0.5 + (sy as f64 + 0.5) / SUPERSAMPLE as f64;
                    let d = cam.ray(u, v);
                    let dn = n.dot(&d);
                    if dn.abs() < 1e-12 {
                        continue;
                    }
                    let s = nt / dn;
                    if s <= 0.0 {
                        continue;
                    }
                    let q = r.inverse() * (s * d - tr);
                    if let Some(rho) = board.reflectance(q.x, q.y) {
                        // Lambertian target: L = ρ E / π.
                        acc += rho * board.irradiance / std::f64::consts::PI;
                    }
                }
            }
            let l = (acc / (SUPERSAMPLE * SUPERSAMPLE) as f64) as f32;
            *o = [l + stray[0], l + stray[1], l + stray[2]];
        }
    });
    let rate = scene.light_rate_e(&scene.mosaic(&rgb));
    let zeros = vec![0f32; w * h];
    let temp = t.sensor.temperature_c;
    let samples = scene.expose(&rate, 1.0, &zeros, exposure_s, temp, frame_number)?;
    let frame = BayerFrame::new(
        w,
        h,
        t.sensor.bit_depth,
        scene.pattern(),
        samples,
        exposure_s,
        timestamp_s,
        temp,
        frame_number,
    )?;
    let corners_px = board
        .inner_corners()
        .iter()
        .map(|p| cam.project_camera_point(&pose.to_camera(p)))
        .collect();
    Ok(CheckerboardCapture {
        frame,
        corners_px,
        pose: *pose,
    })
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
/// noise.
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
