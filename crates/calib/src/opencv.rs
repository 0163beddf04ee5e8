//! OpenCV's calibration file layout (`cv::FileStorage` YAML).

use crate::error::{CalibError, CalibResult};
use gantry_hal::CameraIntrinsics;
use std::path::Path;

/// A camera in OpenCV's file layout.
///
/// OpenCV's calibration file layout: the YAML that `cv::FileStorage` reads and OpenCV's camera
/// calibration sample writes (`image_width`, `image_height`, `nr_of_frames`, `camera_matrix`,
/// `distortion_coefficients`, `avg_reprojection_error`), so that a camera calibrated with OpenCV
/// can be used for a capture and ours in OpenCV.
///
/// The distortion vector is OpenCV's (k1, k2, p1, p2[, k3[, k4, k5, k6 ...]]); terms beyond k3
/// are read only when they are zero (the rational and thin-prism models are not ours).
///
/// # Examples
///
/// ```
/// use calib::{CameraIntrinsics, OpenCvCamera};
///
/// let camera = OpenCvCamera {
///     camera: CameraIntrinsics::radial(1300, 1030, 12150.0, 12170.0, 652.4, 511.8, -0.35, 0.8),
///     frames: 30,
///     avg_reprojection_error: 0.04,
/// };
/// let yaml = camera.to_yaml();
/// assert!(yaml.starts_with("%YAML:1.0") && yaml.contains("camera_matrix: !!opencv-matrix"));
/// let back = OpenCvCamera::from_yaml(&yaml, std::path::Path::new("camera.yml")).unwrap();
/// assert_eq!(back, camera);
/// ```
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct OpenCvCamera {
    /// The camera (matrix, distortion, image size).
    pub camera: CameraIntrinsics,
    /// Number of views of the calibration (`nr_of_frames`).
    pub frames: usize,
    /// Average reprojection error, pixels per point (`avg_reprojection_error`, the figure
    /// `calibrateCamera` returns).
    pub avg_reprojection_error: f64,
}

fn matrix(name: &str, rows: usize, cols: usize, data: &[f64]) -> String {
    let values: Vec<String> = data.iter().map(|v| format!("{v:.16e}")).collect();
    format!(
        "{name}: !!opencv-matrix\n   rows: {rows}\n   cols: {cols}\n   dt: d\n   data: [ {} ]\n",
        values.join(", ")
    )
}

impl OpenCvCamera {
    /// The YAML text.
    pub fn to_yaml(&self) -> String {
        let c = &self.camera;
        let mut s = String::from("%YAML:1.0\n---\n");
        s += &format!("nr_of_frames: {}\n", self.frames);
        s += &format!("image_width: {}\n", c.width);
        s += &format!("image_height: {}\n", c.height);
        s += &matrix(
            "camera_matrix",
            3,
            3,
            &[c.fx, 0.0, c.cx, 0.0, c.fy, c.cy, 0.0, 0.0, 1.0],
        );
        s += &matrix("distortion_coefficients", 5, 1, &c.distortion());
        s += &format!(
            "avg_reprojection_error: {:.16e}\n",
            self.avg_reprojection_error
        );
        s
    }

    /// Parses the YAML text; `path` is used in errors only.
    pub fn from_yaml(text: &str, path: &Path) -> CalibResult<Self> {
        let bad = |detail: String| CalibError::Parse {
            path: path.to_path_buf(),
            detail,
        };
        let scalar = |key: &str| -> CalibResult<Option<f64>> {
            for line in text.lines() {
                if let Some(rest) = line.trim_start().strip_prefix(key) {
                    if let Some(v) = rest.trim_start().strip_prefix(':') {
                        let v = v.trim().trim_matches('"');
                        return v
                            .parse::<f64>()
                            .map(Some)
                            .map_err(|_| bad(format!("{key}: `{v}` is not a number")));
                    }
                }
            }
            Ok(None)
        };
        let block = |key: &str| -> CalibResult<Vec<f64>> {
            let start = text
                .find(&format!("{key}:"))
                .ok_or_else(|| bad(format!("no `{key}`")))?;
            let rest = &text[start..];
            let open = rest
                .find("data:")
                .and_then(|d| rest[d..].find('[').map(|b| d + b + 1))
                .ok_or_else(|| bad(format!("`{key}` without `data: [`")))?;
            let close = rest[open..]
                .find(']')
                .ok_or_else(|| bad(format!("`{key}` data without `]`")))?;
            rest[open..open + close]
                .split(',')
                .map(str::trim)
                .filter(|v| !v.is_empty())
                .map(|v| {
                    v.parse::<f64>()
                        .map_err(|_| bad(format!("{key}: `{v}` is not a number")))
                })
                .collect()
        };
        let need = |key: &str| -> CalibResult<f64> {
            scalar(key)?.ok_or_else(|| bad(format!("no `{key}`")))
        };
        let size = |key: &str| -> CalibResult<usize> {
            let v = need(key)?;
            if v >= 1.0 && v.fract() == 0.0 && v < 1e9 {
                Ok(v as usize)
            } else {
                Err(bad(format!("{key}: {v}")))
            }
        };
        let k = block("camera_matrix")?;
        if k.len() != 9 {
            return Err(bad(format!(
                "camera_matrix has {} entries, 9 expected",
                k.len()
            )));
        }
        if k[1] != 0.0 || k[3] != 0.0 || k[6] != 0.0 || k[7] != 0.0 || k[8] != 1.0 {
            return Err(bad("camera_matrix with skew or not normalised".into()));
        }
        let d = block("distortion_coefficients")?;
        if d.len() < 4 {
            return Err(bad(format!(
                "distortion_coefficients has {} entries, at least 4 expected",
                d.len()
            )));
        }
        if d.iter().skip(5).any(|&v| v != 0.0) {
            return Err(bad(
                "distortion terms beyond k3 (rational or thin-prism model) are not supported"
                    .into(),
            ));
        }
        let camera = CameraIntrinsics {
            width: size("image_width")?,
            height: size("image_height")?,
            fx: k[0],
            fy: k[4],
            cx: k[2],
            cy: k[5],
            k1: d[0],
            k2: d[1],
            p1: d[2],
            p2: d[3],
            k3: d.get(4).copied().unwrap_or(0.0),
        };
        camera.validate()?;
        Ok(Self {
            camera,
            frames: scalar("nr_of_frames")?.map_or(0, |v| v.max(0.0) as usize),
            avg_reprojection_error: scalar("avg_reprojection_error")?.unwrap_or(f64::NAN),
        })
    }

    /// Reads a file.
    pub fn read(path: &Path) -> CalibResult<Self> {
        let text = std::fs::read_to_string(path).map_err(crate::io::io_err(path))?;
        Self::from_yaml(&text, path)
    }

    /// Writes a file, atomically.
    pub fn write(&self, path: &Path) -> CalibResult<()> {
        crate::io::write_atomic(path, self.to_yaml().as_bytes())
    }
}
