//! The versioned calibration file: camera intrinsics and pose, lamp circle, sample sphere.
//!
//! Conventions (identical to the simulator's ground truth, so that its values convert field by
//! field): world frame in metres; pixel (i, j) covers u ∈ [i − ½, i + ½], v ∈ [j − ½, j + ½],
//! its centre at integer coordinates; a camera-frame point (X, Y, Z), Z > 0, has normalised
//! coordinates x = X/Z, y = Y/Z, r² = x² + y², distorted (x, y)·(1 + k1 r² + k2 r⁴) and pixel
//! u = fx·x_d + cx, v = fy·y_d + cy; the pose maps world to camera, p_cam = R·p_world + t; the
//! lamp at turntable angle θ (degrees) is at centre + radius·(cos θ·u + sin θ·(n × u)).

use crate::error::{check_finite, CalibError, CalibResult};
use nalgebra::{Matrix3, Vector3};
use serde::{Deserialize, Serialize};
use std::path::Path;

/// Schema version written into every calibration file.
pub const CALIBRATION_VERSION: u32 = 1;

/// A 3-vector in world coordinates, metres.
pub type Point3 = [f64; 3];

/// Pinhole camera with two-term radial distortion (see the module documentation).
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
}

impl CameraIntrinsics {
    /// Applies the radial distortion to normalised coordinates.
    #[inline]
    pub fn distort(&self, x: f64, y: f64) -> (f64, f64) {
        let r2 = x * x + y * y;
        let f = 1.0 + r2 * (self.k1 + self.k2 * r2);
        (x * f, y * f)
    }

    /// Inverts [`CameraIntrinsics::distort`] (Newton iteration on the radius).
    pub fn undistort(&self, xd: f64, yd: f64) -> (f64, f64) {
        let rd = (xd * xd + yd * yd).sqrt();
        if rd == 0.0 {
            return (xd, yd);
        }
        // Solve r (1 + k1 r² + k2 r⁴) = rd for r.
        let mut r = rd;
        for _ in 0..30 {
            let r2 = r * r;
            let g = r * (1.0 + r2 * (self.k1 + self.k2 * r2)) - rd;
            let dg = 1.0 + 3.0 * self.k1 * r2 + 5.0 * self.k2 * r2 * r2;
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
        (xd * s, yd * s)
    }

    /// Pixel coordinates of a camera-frame point; `None` for points not in front of the camera.
    pub fn project_camera_point(&self, p: &Vector3<f64>) -> Option<[f64; 2]> {
        if !(p.z > 1e-12) {
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

    /// Checks finiteness and positivity of the parameters.
    pub fn validate(&self) -> CalibResult<()> {
        check_finite(
            "camera intrinsics",
            &[self.fx, self.fy, self.cx, self.cy, self.k1, self.k2],
        )?;
        if !(self.fx > 0.0 && self.fy > 0.0) || self.width == 0 || self.height == 0 {
            return Err(CalibError::Invalid(format!(
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

    /// Checks finiteness and orthonormality (|RᵀR − I| < 1e-6, det R > 0).
    pub fn validate(&self) -> CalibResult<()> {
        let flat: Vec<f64> = self.rotation.iter().flatten().copied().collect();
        check_finite("camera pose", &flat)?;
        check_finite("camera pose", &self.translation)?;
        let r = self.rotation_matrix();
        if (r.transpose() * r - Matrix3::identity()).abs().max() > 1e-6 || r.determinant() <= 0.0 {
            return Err(CalibError::Invalid(
                "camera rotation is not a rotation".into(),
            ));
        }
        Ok(())
    }
}

/// Circle traversed by the lamp and the angle convention (see the module documentation).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct LampCircle {
    /// Circle centre, metres.
    pub centre: Point3,
    /// Unit normal of the circle plane; turntable angles grow counter-clockwise about it.
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
    pub fn validate(&self) -> CalibResult<()> {
        check_finite("lamp circle", &self.centre)?;
        check_finite("lamp circle", &self.normal)?;
        check_finite("lamp circle", &self.reference)?;
        check_finite("lamp circle", &[self.radius])?;
        let n = Vector3::from(self.normal);
        let u = Vector3::from(self.reference);
        if !(self.radius > 0.0)
            || (n.norm() - 1.0).abs() > 1e-6
            || (u.norm() - 1.0).abs() > 1e-6
            || n.dot(&u).abs() > 1e-6
        {
            return Err(CalibError::Invalid(
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

/// Residuals of the fits that produced a calibration (absent in ground-truth files).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct FitQuality {
    /// RMS reprojection error of the checkerboard corners after the intrinsic fit, pixels
    /// (per coordinate).
    pub reprojection_rms_px: f64,
    /// Number of checkerboard images used.
    pub target_images: usize,
    /// RMS reprojection error of the digitizer tips after the extrinsic fit, pixels.
    pub extrinsic_rms_px: f64,
    /// RMS distance of the lamp readings from the fitted circle model, metres.
    pub lamp_rms_m: f64,
    /// RMS distance of the sphere readings from the fitted sphere, metres.
    pub sphere_rms_m: f64,
}

/// The versioned calibration file consumed by binning.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Calibration {
    /// Schema version, [`CALIBRATION_VERSION`].
    pub version: u32,
    /// Camera intrinsics (keys `width`, `height`, `fx`, `fy`, `cx`, `cy`, `k1`, `k2`).
    pub camera: CameraIntrinsics,
    /// World-to-camera transform.
    pub pose: CameraPose,
    /// The lamp circle.
    pub lamp: LampCircle,
    /// The sample sphere.
    pub sphere: SphereGeometry,
    /// Fit residuals, when the file was produced by a calibration.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub fit: Option<FitQuality>,
}

impl Calibration {
    /// A calibration from its parts (no fit residuals), version [`CALIBRATION_VERSION`].
    pub fn new(
        camera: CameraIntrinsics,
        pose: CameraPose,
        lamp: LampCircle,
        sphere: SphereGeometry,
    ) -> Self {
        Self {
            version: CALIBRATION_VERSION,
            camera,
            pose,
            lamp,
            sphere,
            fit: None,
        }
    }

    /// A calibration from plain fields: intrinsics (`width`, `height`, `fx`, `fy`, `cx`, `cy`,
    /// `k1`, `k2`), row-major world-to-camera rotation and translation, lamp circle (`centre`,
    /// `normal`, `radius`, `reference`) and sphere (`centre`, `radius`). Validated.
    #[allow(clippy::too_many_arguments)]
    pub fn from_fields(
        intrinsics: (usize, usize, f64, f64, f64, f64, f64, f64),
        rotation: [[f64; 3]; 3],
        translation: Point3,
        lamp_centre: Point3,
        lamp_normal: Point3,
        lamp_radius: f64,
        lamp_reference: Point3,
        sphere_centre: Point3,
        sphere_radius: f64,
    ) -> CalibResult<Self> {
        let (width, height, fx, fy, cx, cy, k1, k2) = intrinsics;
        let c = Self::new(
            CameraIntrinsics {
                width,
                height,
                fx,
                fy,
                cx,
                cy,
                k1,
                k2,
            },
            CameraPose {
                rotation,
                translation,
            },
            LampCircle {
                centre: lamp_centre,
                normal: lamp_normal,
                radius: lamp_radius,
                reference: lamp_reference,
            },
            SphereGeometry {
                centre: sphere_centre,
                radius: sphere_radius,
            },
        );
        c.validate()?;
        Ok(c)
    }

    /// Checks version, finiteness and the geometric constraints of every part.
    pub fn validate(&self) -> CalibResult<()> {
        if self.version != CALIBRATION_VERSION {
            return Err(CalibError::Version {
                found: self.version,
                supported: CALIBRATION_VERSION,
            });
        }
        self.camera.validate()?;
        self.pose.validate()?;
        self.lamp.validate()?;
        check_finite("sphere", &self.sphere.centre)?;
        check_finite("sphere", &[self.sphere.radius])?;
        if !(self.sphere.radius > 0.0) {
            return Err(CalibError::Invalid("sphere radius must be positive".into()));
        }
        Ok(())
    }

    /// World-frame ray through pixel (`u`, `v`): (camera centre, unit direction).
    pub fn pixel_ray_world(&self, u: f64, v: f64) -> (Vector3<f64>, Vector3<f64>) {
        let d = self.pose.dir_to_world(&self.camera.ray(u, v));
        (self.pose.centre(), d)
    }

    /// Lamp position (world, metres) at turntable angle `angle_deg`.
    pub fn lamp_position(&self, angle_deg: f64) -> Vector3<f64> {
        self.lamp.position(angle_deg)
    }

    /// Pixel coordinates of a world point; `None` behind the camera.
    pub fn project(&self, p: &Vector3<f64>) -> Option<[f64; 2]> {
        self.camera.project_camera_point(&self.pose.to_camera(p))
    }

    /// Parses and validates a calibration from JSON text (version checked first).
    pub fn from_json(text: &str) -> CalibResult<Self> {
        let value: serde_json::Value = serde_json::from_str(text)?;
        let found = value
            .get("version")
            .and_then(|v| v.as_u64())
            .ok_or_else(|| CalibError::Invalid("calibration without a version".into()))?;
        if found != CALIBRATION_VERSION as u64 {
            return Err(CalibError::Version {
                found: found.min(u32::MAX as u64) as u32,
                supported: CALIBRATION_VERSION,
            });
        }
        let c: Self = serde_json::from_value(value)?;
        c.validate()?;
        Ok(c)
    }

    /// Pretty JSON text of the calibration.
    pub fn to_json(&self) -> CalibResult<String> {
        Ok(serde_json::to_string_pretty(self)?)
    }

    /// Reads and validates a calibration file.
    pub fn read(path: &Path) -> CalibResult<Self> {
        let text = std::fs::read_to_string(path).map_err(|source| CalibError::Io {
            path: path.to_path_buf(),
            source,
        })?;
        Self::from_json(&text).map_err(|e| match e {
            CalibError::Json(j) => CalibError::Parse {
                path: path.to_path_buf(),
                detail: j.to_string(),
            },
            other => other,
        })
    }

    /// Writes the calibration as pretty JSON, atomically (temporary file + rename).
    pub fn write(&self, path: &Path) -> CalibResult<()> {
        let mut text = self.to_json()?;
        text.push('\n');
        crate::io::write_atomic(path, text.as_bytes())
    }
}
