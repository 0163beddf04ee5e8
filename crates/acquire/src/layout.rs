//! The job directory: where each file of a measurement lives, and how it is read and written
//! (every write is atomic: a temporary file renamed over the target).
//!
//! ```text
//! DIR/job.json               parameters of the job (checked on resume)
//! DIR/calibration.json       geometry used for binning
//! DIR/lamp_constant.json     absolute scale (white reference)
//! DIR/defects.json           hot photosites from the 60 s dark frame
//! DIR/ambient.json           ambient signal rate with the lamp off, DN/s per channel
//! DIR/positions/NNN.samples  BRDF samples of position NNN (checkpoint)
//! DIR/positions/NNN.json     log of position NNN: angle, exposures, faults, timings
//! DIR/frames/NNN.frames      raw frames of position NNN (when kept)
//! DIR/hdr/NNN.exr            HDR radiance (DN/s) of position NNN
//! DIR/truth/NNN.exr          noise-free signal rate (simulator only, when asked for)
//! DIR/brdf.binary            the measured table (MERL format)
//! DIR/counts.bin             samples per bin and channel (u32, MERL order)
//! DIR/report.json            timings, sample counts, coverage, validation, faults
//! DIR/previews/contact_sheet.png   measured vs re-rendered (log scale)
//! ```

use crate::error::{io, AcquireError, Result};
use hdr::DefectMap;
use serde::{Deserialize, Serialize};
use std::path::{Path, PathBuf};

/// The files of one job directory.
#[derive(Debug, Clone)]
pub struct JobDir {
    root: PathBuf,
}

impl JobDir {
    /// The job directory at `root` (nothing is created).
    pub fn new(root: impl Into<PathBuf>) -> Self {
        Self { root: root.into() }
    }
    /// The directory itself.
    pub fn root(&self) -> &Path {
        &self.root
    }
    /// `job.json`.
    pub fn job(&self) -> PathBuf {
        self.root.join("job.json")
    }
    /// `calibration.json`.
    pub fn calibration(&self) -> PathBuf {
        self.root.join("calibration.json")
    }
    /// `ambient.json`.
    pub fn ambient(&self) -> PathBuf {
        self.root.join("ambient.json")
    }
    /// `lamp_constant.json`.
    pub fn lamp_constant(&self) -> PathBuf {
        self.root.join("lamp_constant.json")
    }
    /// `defects.json`.
    pub fn defects(&self) -> PathBuf {
        self.root.join("defects.json")
    }
    /// `positions/NNN.samples`, the checkpoint of position `i`.
    pub fn samples(&self, i: usize) -> PathBuf {
        self.root.join("positions").join(format!("{i:03}.samples"))
    }
    /// `positions/NNN.json`, the log of position `i`.
    pub fn log(&self, i: usize) -> PathBuf {
        self.root.join("positions").join(format!("{i:03}.json"))
    }
    /// `frames/NNN.frames`, the raw frames of position `i`.
    pub fn frames(&self, i: usize) -> PathBuf {
        self.root.join("frames").join(format!("{i:03}.frames"))
    }
    /// `hdr/NNN.exr`, the HDR image of position `i`.
    pub fn hdr(&self, i: usize) -> PathBuf {
        hdr::hdr_path(&self.root, i)
    }
    /// `brdf.binary`, the measured table.
    pub fn table(&self) -> PathBuf {
        self.root.join("brdf.binary")
    }
    /// `counts.bin`.
    pub fn counts(&self) -> PathBuf {
        self.root.join("counts.bin")
    }
    /// `report.json`.
    pub fn report(&self) -> PathBuf {
        self.root.join("report.json")
    }
    /// `previews/contact_sheet.png`.
    pub fn contact_sheet(&self) -> PathBuf {
        self.root.join("previews").join("contact_sheet.png")
    }
    /// Whether position `i` has finished (its log and its samples are on disk).
    pub fn position_done(&self, i: usize) -> bool {
        self.log(i).exists() && self.samples(i).exists()
    }
    /// Creates the sub-directories a capture writes into.
    pub fn create(&self) -> Result<()> {
        for sub in ["positions", "hdr", "previews"] {
            let d = self.root.join(sub);
            std::fs::create_dir_all(&d).map_err(io(&d))?;
        }
        Ok(())
    }
}

/// Writes `bytes` to `path` atomically, creating its parent directory.
pub fn write_atomic(path: &Path, bytes: &[u8]) -> Result<()> {
    if let Some(parent) = path.parent() {
        std::fs::create_dir_all(parent).map_err(io(parent))?;
    }
    brdf::write_atomic(path, bytes)?;
    Ok(())
}

/// Writes `value` as pretty JSON to `path`, atomically.
pub fn write_json<T: Serialize>(path: &Path, value: &T) -> Result<()> {
    let mut text = serde_json::to_vec_pretty(value).map_err(|e| AcquireError::Malformed {
        path: path.to_path_buf(),
        reason: e.to_string(),
    })?;
    text.push(b'\n');
    write_atomic(path, &text)
}

/// Reads JSON from `path`.
pub fn read_json<T: for<'de> Deserialize<'de>>(path: &Path) -> Result<T> {
    let text = std::fs::read(path).map_err(io(path))?;
    serde_json::from_slice(&text).map_err(|e| AcquireError::Malformed {
        path: path.to_path_buf(),
        reason: e.to_string(),
    })
}

/// A lamp constant file: three finite, positive numbers (JSON array).
pub fn read_lamp_constant(path: &Path) -> Result<[f64; 3]> {
    let k: [f64; 3] = read_json(path)?;
    if !k.iter().all(|v| v.is_finite() && *v > 0.0) {
        return Err(AcquireError::Malformed {
            path: path.to_path_buf(),
            reason: format!("lamp constant {k:?} must be three finite positive numbers"),
        });
    }
    Ok(k)
}

/// Hot-pixel list as stored in `DIR/defects.json`.
#[derive(Debug, Serialize, Deserialize)]
pub struct HotPixels {
    /// Sensor columns.
    pub width: usize,
    /// Sensor rows.
    pub height: usize,
    /// Hot photosites, `(x, y)`.
    pub hot: Vec<(usize, usize)>,
}

impl HotPixels {
    /// The hot photosites of `map`.
    pub fn of(map: &DefectMap) -> Self {
        Self {
            width: map.width(),
            height: map.height(),
            hot: map.hot_pixels(),
        }
    }

    /// The defect map of this list; `path` names the file in errors.
    pub fn to_map(&self, path: &Path) -> Result<DefectMap> {
        let n = self.width.saturating_mul(self.height);
        if n == 0 || n > (1 << 28) {
            return Err(AcquireError::Malformed {
                path: path.to_path_buf(),
                reason: format!("sensor size {}x{}", self.width, self.height),
            });
        }
        let mut mask = vec![false; n];
        for &(x, y) in &self.hot {
            if x >= self.width || y >= self.height {
                return Err(AcquireError::Malformed {
                    path: path.to_path_buf(),
                    reason: format!("hot pixel ({x}, {y}) outside the sensor"),
                });
            }
            mask[y * self.width + x] = true;
        }
        Ok(DefectMap::from_mask(self.width, self.height, mask)?)
    }

    /// Reads `DIR/defects.json` as a defect map.
    pub fn read_map(path: &Path) -> Result<DefectMap> {
        read_json::<HotPixels>(path)?.to_map(path)
    }
}
