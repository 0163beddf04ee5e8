//! The versioned calibration file: camera intrinsics and pose, lamp circle, sample sphere.

use crate::error::{CalibError, CalibResult};
use nalgebra::Vector3;
use serde::{Deserialize, Serialize};
use std::io::Write;
use std::path::Path;

/// Schema version written into every calibration file.
pub const CALIBRATION_VERSION: u32 = 2;

/// Oldest schema version still read.
pub const OLDEST_CALIBRATION_VERSION: u32 = 1;

/// The rig geometry, defined once in `gantry-hal`; validation errors map into [`CalibError`].
pub use gantry_hal::{
    CameraIntrinsics, CameraPose, LampCircle, Point3, RigGeometry, SphereGeometry,
};

/// Residuals of the fits that produced a calibration (absent in ground-truth files).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct FitQuality {
    /// RMS reprojection error of the checkerboard corners after the intrinsic fit, pixels
    /// (per coordinate).
    pub reprojection_rms_px: f64,
    /// Number of checkerboard images used.
    pub target_images: usize,
    /// Number of checkerboard images dropped because the board was not found whole in them
    /// (absent, 0, in older files).
    #[serde(default, skip_serializing_if = "is_zero")]
    pub dropped_target_images: usize,
    /// The distortion terms that were fitted (the others held at 0); absent in version-1
    /// files, whose fits had k1 (and k2 when estimated).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub distortion_model: Option<crate::intrinsics::DistortionModel>,
    /// RMS reprojection error of the digitizer tips after the extrinsic fit, pixels.
    pub extrinsic_rms_px: f64,
    /// RMS distance of the lamp readings from the fitted circle model, metres.
    pub lamp_rms_m: f64,
    /// RMS distance of the sphere readings from the fitted sphere, metres.
    pub sphere_rms_m: f64,
}

fn is_zero(n: &usize) -> bool {
    *n == 0
}

/// The versioned calibration file consumed by binning: the [`RigGeometry`] (keys `camera`,
/// `pose`, `lamp`, `sphere` at the top level; the camera with keys `width`, `height`, `fx`,
/// `fy`, `cx`, `cy`, `k1`, `k2` and, when non-zero, `p1`, `p2`, `k3`), its version and the
/// fit residuals.
///
/// The calibration dereferences to its [`RigGeometry`] (`calibration.camera`, ...), and is
/// `AsRef<RigGeometry>` for code that takes any holder of the rig's geometry (binning).
///
/// The four parts are the rig geometry types of [`RigGeometry`] of `gantry-hal` (re-exported here),
/// which the simulator's ground truth holds too, so `truth.json` and `calibration.json` share
/// their keys and conventions: world frame in metres, pixel centres at integer coordinates,
/// Brown–Conrady distortion (k1, k2, p1, p2, k3 as OpenCV has them), p_cam = R·p_world + t, the
/// lamp at turntable angle θ at centre + radius·(cos θ·u + sin θ·(n × u)) (see [`RigGeometry`] for
/// the details).
///
/// Versions: 1 had two radial terms (k1, k2); 2 adds the optional p1, p2 and k3 (absent means
/// 0). Version-1 files still load.
///
/// # Examples
///
/// ```
/// use calib::{Calibration, CameraIntrinsics, CameraPose, LampCircle, SphereGeometry};
///
/// let calibration = Calibration::new(
///     CameraIntrinsics::radial(1300, 1030, 12150.0, 12170.0, 652.4, 511.8, -0.35, 0.8),
///     CameraPose::look_at([0.0, -1.0, 0.0], [0.0; 3], 0.0),
///     LampCircle { centre: [0.0; 3], normal: [0.0, 0.0, 1.0], radius: 0.5, reference: [0.0, 1.0, 0.0] },
///     SphereGeometry { centre: [0.0; 3], radius: 0.0254 },
/// );
/// calibration.validate().unwrap();
/// let json = serde_json::to_string(&calibration).unwrap();
/// assert!(json.contains("\"fx\"") && !json.contains("\"k3\"")); // zero terms are not written
/// assert_eq!(Calibration::from_json(&json).unwrap(), calibration);
/// // the sphere's centre is seen at the principal point, up to the camera's distortion
/// let [u, v] = calibration.project(&nalgebra::Vector3::zeros()).unwrap();
/// assert!((u - 652.4).abs() < 1e-6 && (v - 511.8).abs() < 1e-6);
/// ```
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Calibration {
    /// Schema version, [`CALIBRATION_VERSION`].
    pub version: u32,
    /// Camera intrinsics and pose, lamp circle, sphere.
    #[serde(flatten)]
    pub rig: RigGeometry,
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
            rig: RigGeometry {
                camera,
                pose,
                lamp,
                sphere,
            },
            fit: None,
        }
    }

    /// Checks version, finiteness and the geometric constraints of every part.
    pub fn validate(&self) -> CalibResult<()> {
        if !(OLDEST_CALIBRATION_VERSION..=CALIBRATION_VERSION).contains(&self.version) {
            return Err(CalibError::Version {
                found: self.version,
                supported: CALIBRATION_VERSION,
            });
        }
        self.rig.validate()?;
        Ok(())
    }

    /// World-frame ray through pixel (`u`, `v`): (camera centre, unit direction).
    pub fn pixel_ray_world(&self, u: f64, v: f64) -> (Vector3<f64>, Vector3<f64>) {
        self.rig.pixel_ray_world(u, v)
    }

    /// Lamp position (world, metres) at turntable angle `angle_deg`.
    pub fn lamp_position(&self, angle_deg: f64) -> Vector3<f64> {
        self.rig.lamp_position(angle_deg)
    }

    /// Pixel coordinates of a world point; `None` behind the camera.
    pub fn project(&self, p: &Vector3<f64>) -> Option<[f64; 2]> {
        self.rig.project(p)
    }

    /// Parses and validates a calibration from JSON text (version checked first; versions
    /// [`OLDEST_CALIBRATION_VERSION`] to [`CALIBRATION_VERSION`] are read, and a file read is
    /// written back at [`CALIBRATION_VERSION`]).
    pub fn from_json(text: &str) -> CalibResult<Self> {
        let value: serde_json::Value = serde_json::from_str(text)?;
        let found = value
            .get("version")
            .and_then(|v| v.as_u64())
            .ok_or_else(|| CalibError::Invalid("calibration without a version".into()))?;
        if !(OLDEST_CALIBRATION_VERSION as u64..=CALIBRATION_VERSION as u64).contains(&found) {
            return Err(CalibError::Version {
                found: found.min(u32::MAX as u64) as u32,
                supported: CALIBRATION_VERSION,
            });
        }
        let mut c: Self = serde_json::from_value(value)?;
        c.validate()?;
        // Version 1 is version 2 without the optional terms.
        c.version = CALIBRATION_VERSION;
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
        brdf::write_atomic_with(path, |w| w.write_all(text.as_bytes())).map_err(|source| {
            CalibError::Io {
                path: path.to_path_buf(),
                source,
            }
        })
    }
}

impl std::ops::Deref for Calibration {
    type Target = RigGeometry;
    fn deref(&self) -> &RigGeometry {
        &self.rig
    }
}

impl std::ops::DerefMut for Calibration {
    fn deref_mut(&mut self) -> &mut RigGeometry {
        &mut self.rig
    }
}

impl AsRef<RigGeometry> for Calibration {
    fn as_ref(&self) -> &RigGeometry {
        &self.rig
    }
}
