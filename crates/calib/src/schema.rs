//! The versioned calibration file: camera intrinsics and pose, lamp circle, sample sphere.
//!
//! The four parts are the rig geometry types of [`gantry_hal::geometry`] (re-exported here),
//! which the simulator's ground truth holds too, so `truth.json` and `calibration.json` share
//! their keys and conventions: world frame in metres, pixel centres at integer coordinates,
//! two-term radial distortion, p_cam = R·p_world + t, the lamp at turntable angle θ at
//! centre + radius·(cos θ·u + sin θ·(n × u)) (see that module for the details).

use crate::error::{CalibError, CalibResult};
use nalgebra::Vector3;
use serde::{Deserialize, Serialize};
use std::path::Path;

/// Schema version written into every calibration file.
pub const CALIBRATION_VERSION: u32 = 1;

/// The rig geometry, defined once in `gantry-hal`; validation errors map into [`CalibError`].
pub use gantry_hal::geometry::{CameraIntrinsics, CameraPose, LampCircle, Point3, SphereGeometry};

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
        self.sphere.validate()?;
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
