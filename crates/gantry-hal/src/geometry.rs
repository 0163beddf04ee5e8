//! Geometry of the rig: camera intrinsics and pose, lamp circle, sample sphere.

use nalgebra::{Matrix3, Rotation3, Vector3};
use serde::{Deserialize, Serialize};

/// A 3-vector in world coordinates, metres.
pub type Point3 = [f64; 3];

/// Why a geometry failed its validation.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum GeometryError {
    /// A value is NaN or infinite; the payload names the part.
    #[error("non-finite value in {0}")]
    NonFinite(&'static str),
    /// A value is finite but out of its valid range (non-positive focal length or radius,
    /// rotation that is not a rotation, non-orthonormal lamp axes).
    #[error("{0}")]
    Invalid(String),
}

/// Result alias of the geometry checks.
pub type GeometryResult<T> = Result<T, GeometryError>;

fn check_finite(what: &'static str, values: &[f64]) -> GeometryResult<()> {
    if values.iter().all(|v| v.is_finite()) {
        Ok(())
    } else {
        Err(GeometryError::NonFinite(what))
    }
}

fn is_zero(v: &f64) -> bool {
    *v == 0.0
}

/// Pinhole camera with Brown–Conrady distortion (conventions in [`RigGeometry`]).
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
    /// Principal point, column (pixels).
    pub cx: f64,
    /// Principal point, row (pixels).
    pub cy: f64,
    /// First radial distortion coefficient.
    pub k1: f64,
    /// Second radial distortion coefficient.
    pub k2: f64,
    /// First tangential (decentring) distortion coefficient.
    #[serde(default, skip_serializing_if = "is_zero")]
    pub p1: f64,
    /// Second tangential (decentring) distortion coefficient.
    #[serde(default, skip_serializing_if = "is_zero")]
    pub p2: f64,
    /// Third radial distortion coefficient (r⁶).
    #[serde(default, skip_serializing_if = "is_zero")]
    pub k3: f64,
}

impl CameraIntrinsics {
    /// The camera matrix entries and the radial terms of a pinhole camera with no tangential
    /// and no r⁶ term (the two-term radial model).
    #[allow(clippy::too_many_arguments)]
    pub fn radial(
        width: usize,
        height: usize,
        fx: f64,
        fy: f64,
        cx: f64,
        cy: f64,
        k1: f64,
        k2: f64,
    ) -> Self {
        Self {
            width,
            height,
            fx,
            fy,
            cx,
            cy,
            k1,
            k2,
            p1: 0.0,
            p2: 0.0,
            k3: 0.0,
        }
    }

    /// The distortion coefficients in OpenCV's order (k1, k2, p1, p2, k3).
    pub fn distortion(&self) -> [f64; 5] {
        [self.k1, self.k2, self.p1, self.p2, self.k3]
    }

    /// Applies the Brown–Conrady distortion to normalised coordinates.
    #[inline]
    pub fn distort(&self, x: f64, y: f64) -> (f64, f64) {
        let r2 = x * x + y * y;
        let f = 1.0 + r2 * (self.k1 + r2 * (self.k2 + r2 * self.k3));
        (
            x * f + 2.0 * self.p1 * x * y + self.p2 * (r2 + 2.0 * x * x),
            y * f + self.p1 * (r2 + 2.0 * y * y) + 2.0 * self.p2 * x * y,
        )
    }

    /// Jacobian of [`CameraIntrinsics::distort`]: [[∂xd/∂x, ∂xd/∂y], [∂yd/∂x, ∂yd/∂y]].
    fn distort_jacobian(&self, x: f64, y: f64) -> [[f64; 2]; 2] {
        let r2 = x * x + y * y;
        let f = 1.0 + r2 * (self.k1 + r2 * (self.k2 + r2 * self.k3));
        // df/d(r²)
        let g = self.k1 + r2 * (2.0 * self.k2 + 3.0 * r2 * self.k3);
        let (p1, p2) = (self.p1, self.p2);
        [
            [
                f + 2.0 * x * x * g + 2.0 * p1 * y + 6.0 * p2 * x,
                2.0 * x * y * g + 2.0 * p1 * x + 2.0 * p2 * y,
            ],
            [
                2.0 * x * y * g + 2.0 * p1 * x + 2.0 * p2 * y,
                f + 2.0 * y * y * g + 6.0 * p1 * y + 2.0 * p2 * x,
            ],
        ]
    }

    /// Inverts [`CameraIntrinsics::distort`]: Newton iteration on the radius for a purely
    /// radial model, on both coordinates when there are tangential terms.
    pub fn undistort(&self, xd: f64, yd: f64) -> (f64, f64) {
        let rd = (xd * xd + yd * yd).sqrt();
        if rd == 0.0 && self.p1 == 0.0 && self.p2 == 0.0 {
            return (xd, yd);
        }
        let (mut x, mut y) = (xd, yd);
        if rd > 0.0 {
            // Solve r (1 + k1 r² + k2 r⁴ + k3 r⁶) = rd for r.
            let mut r = rd;
            for _ in 0..30 {
                let r2 = r * r;
                let g = r * (1.0 + r2 * (self.k1 + r2 * (self.k2 + r2 * self.k3))) - rd;
                let dg = 1.0 + r2 * (3.0 * self.k1 + r2 * (5.0 * self.k2 + 7.0 * r2 * self.k3));
                if dg.abs() < 1e-12 {
                    break;
                }
                let step = g / dg;
                r -= step;
                if step.abs() < 1e-16 * (1.0 + r.abs()) {
                    break;
                }
            }
            let s = r / rd;
            (x, y) = (xd * s, yd * s);
        }
        if self.p1 == 0.0 && self.p2 == 0.0 {
            return (x, y);
        }
        for _ in 0..30 {
            let (fx, fy) = self.distort(x, y);
            let (ex, ey) = (fx - xd, fy - yd);
            let j = self.distort_jacobian(x, y);
            let det = j[0][0] * j[1][1] - j[0][1] * j[1][0];
            if det.is_nan() || det.abs() <= 1e-12 {
                break;
            }
            let dx = (j[1][1] * ex - j[0][1] * ey) / det;
            let dy = (j[0][0] * ey - j[1][0] * ex) / det;
            x -= dx;
            y -= dy;
            if dx.abs().max(dy.abs()) < 1e-16 * (1.0 + x.abs().max(y.abs())) {
                break;
            }
        }
        (x, y)
    }

    /// Pixel coordinates of a camera-frame point; `None` for points not in front of the camera
    /// (and for NaN depths).
    pub fn project_camera_point(&self, p: &Vector3<f64>) -> Option<[f64; 2]> {
        if p.z.is_nan() || p.z <= 1e-12 {
            return None;
        }
        let (xd, yd) = self.distort(p.x / p.z, p.y / p.z);
        Some([self.fx * xd + self.cx, self.fy * yd + self.cy])
    }

    /// Undistorted normalised coordinates (x, y) of the ray through pixel (`u`, `v`).
    pub fn normalised(&self, u: f64, v: f64) -> (f64, f64) {
        self.undistort((u - self.cx) / self.fx, (v - self.cy) / self.fy)
    }

    /// Unit direction, camera frame, of the ray through pixel (`u`, `v`).
    pub fn ray(&self, u: f64, v: f64) -> Vector3<f64> {
        let (x, y) = self.normalised(u, v);
        Vector3::new(x, y, 1.0).normalize()
    }

    /// The same camera with the sensor scaled by `s` (field of view kept; at least 2 × 2
    /// pixels). Pixel edges scale, so a principal point at c moves to (c + ½)·s' − ½ with s' the
    /// realised scale of the rounded sensor size.
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
            ..*self
        }
    }

    /// Checks finiteness, a non-empty sensor and positive focal lengths.
    pub fn validate(&self) -> GeometryResult<()> {
        check_finite(
            "camera intrinsics",
            &[
                self.fx, self.fy, self.cx, self.cy, self.k1, self.k2, self.p1, self.p2, self.k3,
            ],
        )?;
        if self.fx <= 0.0 || self.fy <= 0.0 || self.width == 0 || self.height == 0 {
            return Err(GeometryError::Invalid(format!(
                "camera {}x{} with focal lengths {}, {}",
                self.width, self.height, self.fx, self.fy
            )));
        }
        Ok(())
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
    /// The pose with rotation matrix `r` and translation `t`.
    pub fn from_matrix(r: &Matrix3<f64>, t: &Vector3<f64>) -> Self {
        Self {
            rotation: [
                [r[(0, 0)], r[(0, 1)], r[(0, 2)]],
                [r[(1, 0)], r[(1, 1)], r[(1, 2)]],
                [r[(2, 0)], r[(2, 1)], r[(2, 2)]],
            ],
            translation: [t.x, t.y, t.z],
        }
    }

    /// A camera at `centre` looking at `target` with world +z up in the image (rows grow down),
    /// then rolled by `roll` radians about its optical axis.
    pub fn look_at(centre: Point3, target: Point3, roll: f64) -> Self {
        let c = Vector3::from(centre);
        let z = (Vector3::from(target) - c).normalize();
        let x = z.cross(&Vector3::z()).normalize();
        let y = z.cross(&x);
        let r0 = Matrix3::from_rows(&[x.transpose(), y.transpose(), z.transpose()]);
        let r = Rotation3::from_axis_angle(&Vector3::z_axis(), roll).matrix() * r0;
        Self::from_matrix(&r, &-(r * c))
    }

    /// R as a matrix.
    pub fn rotation_matrix(&self) -> Matrix3<f64> {
        let r = &self.rotation;
        Matrix3::new(
            r[0][0], r[0][1], r[0][2], r[1][0], r[1][1], r[1][2], r[2][0], r[2][1], r[2][2],
        )
    }

    /// t as a vector.
    pub fn translation_vector(&self) -> Vector3<f64> {
        Vector3::from(self.translation)
    }

    /// World point to camera coordinates.
    pub fn to_camera(&self, p: &Vector3<f64>) -> Vector3<f64> {
        self.rotation_matrix() * p + self.translation_vector()
    }

    /// Camera-frame direction to world frame.
    pub fn dir_to_world(&self, d: &Vector3<f64>) -> Vector3<f64> {
        self.rotation_matrix().transpose() * d
    }

    /// Centre of projection in world coordinates, −Rᵀt.
    pub fn centre(&self) -> Vector3<f64> {
        -(self.rotation_matrix().transpose() * self.translation_vector())
    }

    /// Checks finiteness and that R is a rotation (|RᵀR − I| ≤ 1e-6, det R > 0).
    pub fn validate(&self) -> GeometryResult<()> {
        let flat: Vec<f64> = self.rotation.iter().flatten().copied().collect();
        check_finite("camera pose", &flat)?;
        check_finite("camera pose", &self.translation)?;
        let r = self.rotation_matrix();
        if (r.transpose() * r - Matrix3::identity()).abs().max() > 1e-6 || r.determinant() <= 0.0 {
            return Err(GeometryError::Invalid(
                "camera rotation is not a rotation".into(),
            ));
        }
        Ok(())
    }
}

/// Circle traversed by the lamp and the angle convention (see [`RigGeometry`]).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct LampCircle {
    /// Circle centre, metres.
    pub centre: Point3,
    /// Unit normal of the circle plane (the turntable axis); turntable angles grow
    /// counter-clockwise about it.
    pub normal: Point3,
    /// Radius, metres.
    pub radius: f64,
    /// Unit vector from the centre to the lamp at turntable angle 0, perpendicular to `normal`.
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

    /// Checks finiteness, a positive radius and an orthonormal (normal, reference) pair.
    pub fn validate(&self) -> GeometryResult<()> {
        check_finite("lamp circle", &self.centre)?;
        check_finite("lamp circle", &self.normal)?;
        check_finite("lamp circle", &self.reference)?;
        check_finite("lamp circle", &[self.radius])?;
        let n = Vector3::from(self.normal);
        let u = Vector3::from(self.reference);
        if self.radius <= 0.0
            || (n.norm() - 1.0).abs() > 1e-6
            || (u.norm() - 1.0).abs() > 1e-6
            || n.dot(&u).abs() > 1e-6
        {
            return Err(GeometryError::Invalid(
                "lamp circle needs a positive radius and orthonormal normal/reference".into(),
            ));
        }
        Ok(())
    }
}

/// The spherical material sample.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct SphereGeometry {
    /// Centre, metres.
    pub centre: Point3,
    /// Radius, metres.
    pub radius: f64,
}

impl SphereGeometry {
    /// Checks finiteness and a positive radius.
    pub fn validate(&self) -> GeometryResult<()> {
        check_finite("sphere", &self.centre)?;
        check_finite("sphere", &[self.radius])?;
        if self.radius <= 0.0 {
            return Err(GeometryError::Invalid(
                "sphere radius must be positive".into(),
            ));
        }
        Ok(())
    }
}

/// The whole geometry of the rig: camera intrinsics and pose, lamp circle and sample sphere;
/// what a capture needs to turn pixels into world rays and turntable angles into lamp
/// positions. JSON keys `camera`, `pose`, `lamp`, `sphere`.
///
/// Its parts are the one definition shared by the simulator's ground truth (`hal-sim`, written as
/// `truth.json`) and the calibration file (`calib`, `calibration.json`): both files hold
/// these structs with the same keys.
///
/// Conventions: right-handed world frame in metres (that of the contact digitizer); pixel
/// (i, j) covers u ∈ [i − ½, i + ½], v ∈ [j − ½, j + ½], its centre at integer coordinates; a
/// camera-frame point (X, Y, Z), Z > 0, has normalised coordinates x = X/Z, y = Y/Z,
/// r² = x² + y², distorted by the Brown–Conrady model that OpenCV uses,
/// x_d = x·(1 + k1 r² + k2 r⁴ + k3 r⁶) + 2 p1 x y + p2 (r² + 2x²),
/// y_d = y·(1 + k1 r² + k2 r⁴ + k3 r⁶) + p1 (r² + 2y²) + 2 p2 x y
/// (every term optional: absent terms are 0, and zero terms are not written), and pixel
/// u = fx·x_d + cx, v = fy·y_d + cy; the pose maps world to camera, p_cam = R·p_world + t, R row-major; the lamp
/// at turntable angle θ (degrees) is at centre + radius·(cos θ·u + sin θ·(n × u)), with n the
/// circle normal and u the reference direction.
///
/// The `validate` methods report NaN/infinite values and violated constraints as a
/// [`GeometryError`].
///
/// # Examples
///
/// A distortion-free camera one metre in front of the sphere and a lamp circle of radius 0.5 m
/// about the vertical axis: the sphere's centre projects to the principal point, the pixel ray
/// through it points back at the centre, and a quarter turn moves the lamp a quarter round.
///
/// ```
/// use gantry_hal::{CameraIntrinsics, CameraPose, LampCircle, RigGeometry, SphereGeometry};
/// use nalgebra::Vector3;
///
/// let rig = RigGeometry {
///     camera: CameraIntrinsics::radial(640, 480, 2000.0, 2000.0, 320.0, 240.0, 0.0, 0.0),
///     pose: CameraPose::look_at([0.0, -1.0, 0.0], [0.0, 0.0, 0.0], 0.0),
///     lamp: LampCircle {
///         centre: [0.0; 3],
///         normal: [0.0, 0.0, 1.0],
///         radius: 0.5,
///         reference: [0.0, -1.0, 0.0], // at angle 0 the lamp is beside the camera
///     },
///     sphere: SphereGeometry { centre: [0.0; 3], radius: 0.0254 },
/// };
/// rig.validate().unwrap();
/// let [u, v] = rig.project(&Vector3::zeros()).unwrap();
/// assert!((u - 320.0).abs() < 1e-9 && (v - 240.0).abs() < 1e-9);
/// let (origin, dir) = rig.pixel_ray_world(320.0, 240.0);
/// assert!((origin + dir).norm() < 1e-9); // from (0, −1, 0) along +y
/// let lamp = rig.lamp_position(90.0);
/// assert!((lamp - Vector3::new(0.5, 0.0, 0.0)).norm() < 1e-9);
/// ```
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct RigGeometry {
    /// Camera intrinsics.
    pub camera: CameraIntrinsics,
    /// World-to-camera transform.
    pub pose: CameraPose,
    /// The lamp circle.
    pub lamp: LampCircle,
    /// The sample sphere.
    pub sphere: SphereGeometry,
}

impl RigGeometry {
    /// World-frame ray through pixel (`u`, `v`), lens distortion removed: (camera centre, unit
    /// direction).
    pub fn pixel_ray_world(&self, u: f64, v: f64) -> (Vector3<f64>, Vector3<f64>) {
        let d = self.pose.dir_to_world(&self.camera.ray(u, v));
        (self.pose.centre(), d)
    }

    /// Pixel coordinates of a world point; `None` behind the camera.
    pub fn project(&self, p: &Vector3<f64>) -> Option<[f64; 2]> {
        self.camera.project_camera_point(&self.pose.to_camera(p))
    }

    /// Lamp position (world, metres) at turntable angle `angle_deg`.
    pub fn lamp_position(&self, angle_deg: f64) -> Vector3<f64> {
        self.lamp.position(angle_deg)
    }

    /// Checks every part.
    pub fn validate(&self) -> GeometryResult<()> {
        self.camera.validate()?;
        self.pose.validate()?;
        self.lamp.validate()?;
        self.sphere.validate()
    }
}

impl AsRef<RigGeometry> for RigGeometry {
    fn as_ref(&self) -> &RigGeometry {
        self
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A wider lens than the rig's, with off-centre principal point, non-square pixels and
    /// strong barrel distortion, so every term of the model matters.
    fn camera() -> CameraIntrinsics {
        CameraIntrinsics {
            width: 1600,
            height: 1200,
            fx: 2_400.0,
            fy: 2_390.0,
            cx: 812.5,
            cy: 588.0,
            k1: -0.2,
            k2: 0.05,
            p1: 0.0,
            p2: 0.0,
            k3: 0.0,
        }
    }

    /// The camera of OpenCV's sample photographs (its five-term fit): strong barrel
    /// distortion with tangential terms.
    fn brown_conrady() -> CameraIntrinsics {
        CameraIntrinsics {
            p1: 0.0018,
            p2: -0.0003,
            k3: 0.25,
            k1: -0.265,
            k2: -0.047,
            ..camera()
        }
    }

    fn pose() -> CameraPose {
        CameraPose::look_at([0.004, -1.0, 0.006], [0.0, 0.0, 0.0], 0.4f64.to_radians())
    }

    fn lamp() -> LampCircle {
        LampCircle {
            centre: [0.0012, 0.0008, -0.0015],
            normal: [0.0, 0.0, 1.0],
            radius: 0.5,
            reference: [0.0, 1.0, 0.0],
        }
    }

    fn sphere() -> SphereGeometry {
        SphereGeometry {
            centre: [0.0005, -0.0003, 0.0002],
            radius: 0.0254,
        }
    }

    #[test]
    fn undistort_inverts_distort() {
        for c in [camera(), brown_conrady()] {
            for &(x, y) in &[
                (0.0, 0.0),
                (0.05, -0.03),
                (-0.07, 0.06),
                (0.2, 0.1),
                (-0.6, 0.45),
            ] {
                let (xd, yd) = c.distort(x, y);
                let (xu, yu) = c.undistort(xd, yd);
                assert!((xu - x).abs() < 1e-13 && (yu - y).abs() < 1e-13, "{x} {y}");
            }
        }
    }

    #[test]
    fn distortion_jacobian_matches_finite_differences() {
        let c = brown_conrady();
        let (x, y, h) = (0.31, -0.22, 1e-6);
        let j = c.distort_jacobian(x, y);
        let (a, b) = (c.distort(x + h, y), c.distort(x - h, y));
        let (e, f) = (c.distort(x, y + h), c.distort(x, y - h));
        let num = [
            [(a.0 - b.0) / (2.0 * h), (e.0 - f.0) / (2.0 * h)],
            [(a.1 - b.1) / (2.0 * h), (e.1 - f.1) / (2.0 * h)],
        ];
        for r in 0..2 {
            for k in 0..2 {
                assert!((j[r][k] - num[r][k]).abs() < 1e-8, "{j:?} {num:?}");
            }
        }
    }

    /// The tangential terms are OpenCV's: a point on the x axis moves by p2·3x² in x and by
    /// p1·x² in y.
    #[test]
    fn tangential_terms_follow_opencv() {
        let c = CameraIntrinsics {
            k1: 0.0,
            k2: 0.0,
            p1: 0.01,
            p2: 0.02,
            ..camera()
        };
        let (xd, yd) = c.distort(0.5, 0.0);
        assert!((xd - (0.5 + 0.02 * 3.0 * 0.25)).abs() < 1e-15);
        assert!((yd - 0.01 * 0.25).abs() < 1e-15);
    }

    #[test]
    fn ray_and_projection_agree() {
        let c = camera();
        for &(u, v) in &[(0.0, 0.0), (652.4, 511.8), (1299.0, 3.0), (17.5, 1029.0)] {
            let d = c.ray(u, v);
            assert!((d.norm() - 1.0).abs() < 1e-14);
            let p = c.project_camera_point(&(2.5 * d)).unwrap();
            assert!(
                (p[0] - u).abs() < 1e-9 && (p[1] - v).abs() < 1e-9,
                "{u} {v} {p:?}"
            );
            let (x, y) = c.normalised(u, v);
            assert!((x - d.x / d.z).abs() < 1e-14 && (y - d.y / d.z).abs() < 1e-14);
        }
        assert_eq!(c.project_camera_point(&Vector3::new(0.0, 0.0, -1.0)), None);
        assert_eq!(
            c.project_camera_point(&Vector3::new(0.0, 0.0, f64::NAN)),
            None
        );
    }

    #[test]
    fn scaling_keeps_the_field_of_view() {
        let c = camera();
        let s = c.scaled(0.1);
        assert_eq!((s.width, s.height), (160, 120));
        // The sensor's outer pixel edges see the same rays at both resolutions.
        let (w, h) = (c.width as f64, c.height as f64);
        for &(u, v) in &[(-0.5, -0.5), (w - 0.5, h - 0.5), (-0.5, h - 0.5)] {
            let su = (u + 0.5) * 0.1 - 0.5;
            let sv = (v + 0.5) * 0.1 - 0.5;
            assert!((c.ray(u, v) - s.ray(su, sv)).norm() < 1e-12);
        }
        assert_eq!(c.scaled(1e-6).width, 2);
    }

    #[test]
    fn look_at_sees_its_target_upright() {
        let p = CameraPose::look_at([0.004, -1.0, 0.006], [0.0, 0.0, 0.0], 0.0);
        p.validate().unwrap();
        assert!((p.centre() - Vector3::new(0.004, -1.0, 0.006)).norm() < 1e-14);
        let t = p.to_camera(&Vector3::zeros());
        assert!(t.x.abs() < 1e-14 && t.y.abs() < 1e-14 && t.z > 0.0);
        // World +z points up in the image: rows grow downwards.
        let up = p.to_camera(&Vector3::new(0.0, 0.0, 0.01));
        assert!(up.y < 0.0 && up.x.abs() < 1e-4);
        // Roll turns the image about the optical axis by that angle.
        let rolled = CameraPose::look_at([0.004, -1.0, 0.006], [0.0, 0.0, 0.0], 0.3);
        let a = rolled
            .dir_to_world(&Vector3::x())
            .angle(&p.dir_to_world(&Vector3::x()));
        assert!((a - 0.3).abs() < 1e-12);
    }

    #[test]
    fn pose_matrix_round_trips() {
        let p = pose();
        let q = CameraPose::from_matrix(&p.rotation_matrix(), &p.translation_vector());
        assert_eq!(p, q);
        let w = Vector3::new(0.01, 0.02, -0.03);
        let back = p.dir_to_world(&(p.to_camera(&w) - p.translation_vector()));
        assert!((back - w).norm() < 1e-15);
    }

    #[test]
    fn lamp_moves_counter_clockwise_on_its_circle() {
        let l = lamp();
        let c = Vector3::from(l.centre);
        assert!((l.position(0.0) - c - Vector3::y() * 0.5).norm() < 1e-15);
        assert!((l.position(90.0) - c + Vector3::x() * 0.5).norm() < 1e-15);
        for a in [13.0, 200.0, -45.0] {
            let d = l.position(a) - c;
            assert!((d.norm() - 0.5).abs() < 1e-15 && d.z.abs() < 1e-15);
        }
    }

    #[test]
    fn validation_reports_the_kind_of_fault() {
        camera().validate().unwrap();
        pose().validate().unwrap();
        lamp().validate().unwrap();
        sphere().validate().unwrap();
        let mut c = camera();
        c.k2 = f64::INFINITY;
        assert_eq!(
            c.validate(),
            Err(GeometryError::NonFinite("camera intrinsics"))
        );
        let mut c = camera();
        c.fy = 0.0;
        assert!(matches!(c.validate(), Err(GeometryError::Invalid(_))));
        let mut p = pose();
        p.translation[2] = f64::NAN;
        assert_eq!(p.validate(), Err(GeometryError::NonFinite("camera pose")));
        let mut p = pose();
        p.rotation[0][0] = 2.0;
        assert!(matches!(p.validate(), Err(GeometryError::Invalid(_))));
        // A reflection is orthonormal but not a rotation.
        let mut p = pose();
        p.rotation[2] = p.rotation[2].map(|x| -x);
        assert!(matches!(p.validate(), Err(GeometryError::Invalid(_))));
        let mut l = lamp();
        l.radius = f64::NAN;
        assert_eq!(l.validate(), Err(GeometryError::NonFinite("lamp circle")));
        let mut l = lamp();
        l.reference = [0.0, 0.6, 0.8];
        assert!(matches!(l.validate(), Err(GeometryError::Invalid(_))));
        let mut s = sphere();
        s.radius = -1.0;
        assert!(matches!(s.validate(), Err(GeometryError::Invalid(_))));
        s.centre[1] = f64::NAN;
        assert_eq!(s.validate(), Err(GeometryError::NonFinite("sphere")));
    }

    /// Keys of a JSON object, sorted.
    fn keys(v: &serde_json::Value) -> Vec<String> {
        let mut k: Vec<String> = v.as_object().unwrap().keys().cloned().collect();
        k.sort();
        k
    }

    fn round_trips<T>(x: &T) -> serde_json::Value
    where
        T: Serialize + for<'de> Deserialize<'de> + PartialEq + std::fmt::Debug,
    {
        let text = serde_json::to_string(x).unwrap();
        let back: T = serde_json::from_str(&text).unwrap();
        assert_eq!(&back, x);
        serde_json::from_str(&text).unwrap()
    }

    /// The layout of docs/calib.md, "Calibration file": the `camera`, `pose`, `lamp` and
    /// `sphere` objects of `calibration.json` and `truth.json`.
    #[test]
    fn json_layout_is_the_documented_one() {
        let c = round_trips(&camera());
        assert_eq!(
            keys(&c),
            ["cx", "cy", "fx", "fy", "height", "k1", "k2", "width"]
        );
        assert_eq!(c["width"], 1600);
        assert_eq!(c["fx"], 2_400.0);
        assert_eq!(c["k1"], -0.2);
        let p = round_trips(&pose());
        assert_eq!(keys(&p), ["rotation", "translation"]);
        let rows = p["rotation"].as_array().unwrap();
        assert_eq!(rows.len(), 3);
        // Row-major: the first row is the first row of R.
        let r = pose().rotation_matrix();
        for (j, x) in rows[0].as_array().unwrap().iter().enumerate() {
            assert_eq!(x.as_f64().unwrap(), r[(0, j)]);
        }
        assert_eq!(p["translation"].as_array().unwrap().len(), 3);
        let l = round_trips(&lamp());
        assert_eq!(keys(&l), ["centre", "normal", "radius", "reference"]);
        assert_eq!(l["radius"], 0.5);
        assert_eq!(l["reference"], serde_json::json!([0.0, 1.0, 0.0]));
        let s = round_trips(&sphere());
        assert_eq!(keys(&s), ["centre", "radius"]);
        assert_eq!(s["radius"], 0.0254);
        // The documented text parses.
        let doc: CameraIntrinsics = serde_json::from_str(
            r#"{ "width": 1300, "height": 1030, "fx": 12150.0, "fy": 12170.0,
                 "cx": 652.4, "cy": 511.8, "k1": -0.35, "k2": 0.8 }"#,
        )
        .unwrap();
        assert_eq!((doc.width, doc.height), (1300, 1030));
        assert_eq!(
            [doc.fx, doc.fy, doc.cx, doc.cy],
            [12150.0, 12170.0, 652.4, 511.8]
        );
        assert_eq!([doc.k1, doc.k2], [-0.35, 0.8]);
    }
}
