//! Ground truth of the simulated rig as plain serialisable structs: camera intrinsics and pose,
//! lamp circle and radiant intensity, sample sphere, sensor parameters.
//!
//! World frame: right-handed, metres, the turntable axis along +z through the lamp-circle centre,
//! the sample sphere near the origin and the camera on the −y side looking towards +y. The
//! contact digitizer reports points in this frame.

use nalgebra::{Matrix3, Rotation3, Vector3};
use serde::{Deserialize, Serialize};

/// A 3-vector in world coordinates (metres).
pub type Point3 = [f64; 3];

/// Pinhole camera with two-term radial distortion.
///
/// A point with camera coordinates (X, Y, Z), Z > 0, projects to normalised x = X/Z, y = Y/Z,
/// r² = x² + y², distorted (x, y)·(1 + k1 r² + k2 r⁴), pixel u = fx·x_d + cx, v = fy·y_d + cy.
/// Pixel (i, j) covers u ∈ [i − ½, i + ½]: its centre is at integer coordinates.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct CameraIntrinsics {
    /// Sensor columns.
    pub width: usize,
    /// Sensor rows.
    pub height: usize,
    /// Focal length in pixels, horizontal.
    pub fx: f64,
    /// Focal length in pixels, vertical.
    pub fy: f64,
    /// Principal point, column.
    pub cx: f64,
    /// Principal point, row.
    pub cy: f64,
    /// First radial distortion coefficient.
    pub k1: f64,
    /// Second radial distortion coefficient.
    pub k2: f64,
}

impl CameraIntrinsics {
    /// Distorts normalised coordinates.
    #[inline]
    pub fn distort(&self, x: f64, y: f64) -> (f64, f64) {
        let r2 = x * x + y * y;
        let f = 1.0 + self.k1 * r2 + self.k2 * r2 * r2;
        (x * f, y * f)
    }

    /// Inverts [`CameraIntrinsics::distort`] by fixed-point iteration.
    #[inline]
    pub fn undistort(&self, xd: f64, yd: f64) -> (f64, f64) {
        let (mut x, mut y) = (xd, yd);
        for _ in 0..20 {
            let r2 = x * x + y * y;
            let f = 1.0 + self.k1 * r2 + self.k2 * r2 * r2;
            let (nx, ny) = (xd / f, yd / f);
            let done = (nx - x).abs() + (ny - y).abs() < 1e-15;
            x = nx;
            y = ny;
            if done {
                break;
            }
        }
        (x, y)
    }

    /// Pixel coordinates of a point given in camera coordinates (`None` behind the camera).
    pub fn project_camera_point(&self, p: &Vector3<f64>) -> Option<[f64; 2]> {
        if p.z <= 1e-12 {
            return None;
        }
        let (xd, yd) = self.distort(p.x / p.z, p.y / p.z);
        Some([self.fx * xd + self.cx, self.fy * yd + self.cy])
    }

    /// Unit ray direction (camera coordinates) through pixel coordinates (`u`, `v`).
    pub fn ray(&self, u: f64, v: f64) -> Vector3<f64> {
        let (x, y) = self.undistort((u - self.cx) / self.fx, (v - self.cy) / self.fy);
        Vector3::new(x, y, 1.0).normalize()
    }

    /// The same camera with the sensor scaled by `s` (field of view kept).
    pub fn scaled(&self, s: f64) -> Self {
        let width = ((self.width as f64 * s).round() as usize).max(2);
        let height = ((self.height as f64 * s).round() as usize).max(2);
        let sx = width as f64 / self.width as f64;
        let sy = height as f64 / self.height as f64;
        Self {
            width,
            height,
            fx: self.fx * sx,
            fy: self.fy * sy,
            cx: (self.cx + 0.5) * sx - 0.5,
            cy: (self.cy + 0.5) * sy - 0.5,
            k1: self.k1,
            k2: self.k2,
        }
    }
}

/// Rigid transform from world to camera coordinates: p_cam = R·p_world + t.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct CameraPose {
    /// Rotation matrix R, row-major.
    pub rotation: [[f64; 3]; 3],
    /// Translation t, metres.
    pub translation: Point3,
}

impl CameraPose {
    /// A camera at `centre` looking at `target` with world +z up in the image (rows grow down),
    /// then rolled by `roll` radians about its optical axis.
    pub fn look_at(centre: Point3, target: Point3, roll: f64) -> Self {
        let c = Vector3::from(centre);
        let z = (Vector3::from(target) - c).normalize();
        let up = Vector3::z();
        let x = z.cross(&up).normalize();
        let y = z.cross(&x);
        let r0 = Matrix3::from_rows(&[x.transpose(), y.transpose(), z.transpose()]);
        let roll_m = Rotation3::from_axis_angle(&Vector3::z_axis(), roll);
        let r = roll_m.matrix() * r0;
        let t = -(r * c);
        Self {
            rotation: [
                [r[(0, 0)], r[(0, 1)], r[(0, 2)]],
                [r[(1, 0)], r[(1, 1)], r[(1, 2)]],
                [r[(2, 0)], r[(2, 1)], r[(2, 2)]],
            ],
            translation: [t.x, t.y, t.z],
        }
    }

    /// R as a matrix.
    pub fn rotation_matrix(&self) -> Matrix3<f64> {
        let r = &self.rotation;
        Matrix3::new(
            r[0][0], r[0][1], r[0][2], r[1][0], r[1][1], r[1][2], r[2][0], r[2][1], r[2][2],
        )
    }

    /// World point to camera coordinates.
    pub fn to_camera(&self, p: &Vector3<f64>) -> Vector3<f64> {
        self.rotation_matrix() * p + Vector3::from(self.translation)
    }

    /// Camera direction to world direction.
    pub fn dir_to_world(&self, d: &Vector3<f64>) -> Vector3<f64> {
        self.rotation_matrix().transpose() * d
    }

    /// Centre of projection in world coordinates, −Rᵀt.
    pub fn centre(&self) -> Vector3<f64> {
        -(self.rotation_matrix().transpose() * Vector3::from(self.translation))
    }
}

/// The circle on which the lamp moves, and the angle convention.
///
/// Lamp position at turntable angle θ (degrees): centre + radius·(cos θ·u + sin θ·(n × u)),
/// where n is `normal` and u is `reference` (the unit direction from the centre to the lamp at
/// θ = 0, perpendicular to n).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct LampCircle {
    /// Circle centre, metres.
    pub centre: Point3,
    /// Unit normal of the circle plane (the turntable axis).
    pub normal: Point3,
    /// Circle radius, metres.
    pub radius: f64,
    /// Unit vector from the centre to the lamp at angle 0.
    pub reference: Point3,
}

impl LampCircle {
    /// Lamp position at turntable angle `angle_deg`.
    pub fn position(&self, angle_deg: f64) -> Vector3<f64> {
        let n = Vector3::from(self.normal);
        let u = Vector3::from(self.reference);
        let v = n.cross(&u);
        let (s, c) = angle_deg.to_radians().sin_cos();
        Vector3::from(self.centre) + self.radius * (c * u + s * v)
    }
}

/// The light source: a small Lambertian disc facing the sphere.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct LampTruth {
    /// Circle traversed by the disc centre.
    pub circle: LampCircle,
    /// Disc radius, metres.
    pub disc_radius: f64,
    /// Radiant intensity along the disc axis per RGB channel, W/sr.
    pub radiant_intensity: [f64; 3],
    /// Warm-up time after switching on, seconds.
    pub warm_up_s: f64,
}

impl LampTruth {
    /// Irradiance per channel (W/m²) on a surface element at `p` with unit normal `n`: on-axis
    /// Lambertian-disc falloff I/(d² + a²) times foreshortening cos θi; zero when the lamp is
    /// below the element's horizon.
    pub fn irradiance(&self, angle_deg: f64, p: &Vector3<f64>, n: &Vector3<f64>) -> [f64; 3] {
        let l = self.circle.position(angle_deg) - p;
        let d2 = l.norm_squared();
        let cos_i = n.dot(&l) / d2.sqrt();
        if cos_i <= 0.0 {
            return [0.0; 3];
        }
        let g = cos_i / (d2 + self.disc_radius * self.disc_radius);
        self.radiant_intensity.map(|i| i * g)
    }
}

/// The spherical material sample.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct SphereTruth {
    /// Centre, metres.
    pub centre: Point3,
    /// Radius, metres.
    pub radius: f64,
}

/// Sensor model parameters.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct SensorTruth {
    /// Quantum efficiency of the red, green and blue filtered photosites.
    pub quantum_efficiency: [f64; 3],
    /// Photo-electrons per second per unit radiance (W m⁻² sr⁻¹) at unit quantum efficiency:
    /// pixel area × lens solid angle × photons per joule, folded into one number.
    pub responsivity: f64,
    /// Conversion gain, electrons per DN.
    pub gain_e_per_dn: f64,
    /// Read noise, electrons RMS.
    pub read_noise_e: f64,
    /// Full-well capacity, electrons.
    pub full_well_e: f64,
    /// Black level (offset), DN.
    pub black_level_dn: f64,
    /// Bits per sample.
    pub bit_depth: u8,
    /// Mean dark current at the reference temperature, electrons per second.
    pub dark_current_e_per_s: f64,
    /// Spread of the per-pixel dark current (log-normal sigma).
    pub dark_current_log_sigma: f64,
    /// Reference temperature of `dark_current_e_per_s`, °C.
    pub dark_reference_c: f64,
    /// Temperature rise that doubles the dark current, °C.
    pub dark_doubling_c: f64,
    /// Sensor temperature during operation, °C.
    pub temperature_c: f64,
    /// Fraction of photosites that are hot.
    pub hot_pixel_fraction: f64,
    /// Range of the hot pixels' dark signal in a 60 s dark frame at the operating temperature,
    /// DN above black (log-uniform).
    pub hot_pixel_dn_60s: [f64; 2],
    /// Photo-response non-uniformity: relative sigma of the per-pixel gain.
    pub prnu_sigma: f64,
    /// Gaussian defocus blur, sigma in pixels (0 = sharp).
    pub defocus_sigma_px: f64,
}

impl Default for SensorTruth {
    fn default() -> Self {
        Self {
            quantum_efficiency: [0.42, 0.55, 0.38],
            responsivity: 4.0e4,
            gain_e_per_dn: 17.0,
            read_noise_e: 12.0,
            full_well_e: 18_000.0,
            black_level_dn: 4.0,
            bit_depth: 10,
            dark_current_e_per_s: 0.05,
            dark_current_log_sigma: 0.3,
            dark_reference_c: 25.0,
            dark_doubling_c: 6.3,
            temperature_c: 25.0,
            hot_pixel_fraction: 2e-4,
            hot_pixel_dn_60s: [40.0, 400.0],
            prnu_sigma: 0.01,
            defocus_sigma_px: 0.0,
        }
    }
}

impl SensorTruth {
    /// Dark current multiplier at `temp_c` relative to the reference temperature.
    pub fn dark_temperature_factor(&self, temp_c: f64) -> f64 {
        ((temp_c - self.dark_reference_c) / self.dark_doubling_c).exp2()
    }

    /// Largest sample value, 2^bit_depth − 1.
    pub fn max_dn(&self) -> f64 {
        ((1u32 << self.bit_depth) - 1) as f64
    }
}

/// Everything the simulator knows about its scene.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct SceneTruth {
    /// Camera intrinsics at the simulated resolution.
    pub camera: CameraIntrinsics,
    /// World-to-camera transform.
    pub pose: CameraPose,
    /// The lamp.
    pub lamp: LampTruth,
    /// The sample.
    pub sphere: SphereTruth,
    /// The sensor.
    pub sensor: SensorTruth,
    /// Stray-light radiance floor of the matte-black room, per channel, W m⁻² sr⁻¹.
    pub stray_radiance: [f64; 3],
    /// Name of the sample's BRDF.
    pub material: String,
}
