//! The rig configuration file in TOML.

use crate::error::{HalError, HalResult};
use crate::frame::BayerPattern;
use crate::grbl::GrblConfig;
use crate::unpack::Bayer10Format;
use serde::{Deserialize, Serialize};
use std::path::Path;

/// Which devices a rig configuration describes.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, Default)]
#[serde(rename_all = "snake_case")]
pub enum Backend {
    /// The physically simulated rig of `hal-sim` (configured by the `[sim]` table).
    #[default]
    Sim,
    /// Real hardware: GRBL turntable/lamp, V4L2 camera.
    Real,
}

/// The whole rig configuration file (`docs/rig.example.toml` is a full, commented example).
///
/// # Examples
///
/// ```
/// use gantry_hal::{Backend, ErrorKind, RigConfig};
///
/// let sim = RigConfig::from_toml_str("backend = \"sim\"\n[sim]\nseed = 1\n").unwrap();
/// assert_eq!(sim.backend, Backend::Sim);
/// // the configuration survives a round trip through its TOML form
/// assert_eq!(RigConfig::from_toml_str(&sim.to_toml_string().unwrap()).unwrap(), sim);
/// // a real rig needs its motion controller and camera sections
/// let err = RigConfig::from_toml_str("backend = \"real\"").unwrap_err();
/// assert_eq!(err.kind(), ErrorKind::Config);
/// ```
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, Default)]
#[serde(deny_unknown_fields)]
pub struct RigConfig {
    /// `sim` or `real`.
    #[serde(default)]
    pub backend: Backend,
    /// GRBL motion controller (turntable axis and lamp output), for `backend = "real"`.
    #[serde(default)]
    pub motion: Option<GrblConfig>,
    /// V4L2 camera, for `backend = "real"`.
    #[serde(default)]
    pub camera: Option<V4lCameraConfig>,
    /// USB devices that must be present before a real rig is opened.
    #[serde(default)]
    pub usb: Vec<UsbDeviceSpec>,
    /// Settings of the simulated rig, interpreted by `hal-sim` (`hal_sim::SimConfig`).
    #[serde(default)]
    pub sim: Option<toml::Table>,
}

impl RigConfig {
    /// Parses a configuration from TOML text and checks its consistency.
    pub fn from_toml_str(text: &str) -> HalResult<Self> {
        let cfg: RigConfig = toml::from_str(text).map_err(|e| HalError::Config(e.to_string()))?;
        cfg.validate()?;
        Ok(cfg)
    }

    /// Reads and parses a configuration file.
    pub fn load(path: &Path) -> HalResult<Self> {
        let text = std::fs::read_to_string(path)
            .map_err(|e| HalError::Config(format!("{}: {e}", path.display())))?;
        Self::from_toml_str(&text)
    }

    /// Serialises to TOML.
    pub fn to_toml_string(&self) -> HalResult<String> {
        toml::to_string_pretty(self).map_err(|e| HalError::Config(e.to_string()))
    }

    /// Checks that the sections the backend needs are present and sane.
    pub fn validate(&self) -> HalResult<()> {
        if self.backend == Backend::Real {
            let m = self.motion.as_ref().ok_or_else(|| {
                HalError::Config("backend = \"real\" needs a [motion] section".into())
            })?;
            if !(m.speed_deg_per_s > 0.0 && m.speed_deg_per_s.is_finite()) {
                return Err(HalError::Config(format!(
                    "motion.speed_deg_per_s = {}",
                    m.speed_deg_per_s
                )));
            }
            if !"XYZ".contains(m.axis) {
                return Err(HalError::Config(format!("motion.axis = '{}'", m.axis)));
            }
            if self.camera.is_none() {
                return Err(HalError::Config(
                    "backend = \"real\" needs a [camera] section".into(),
                ));
            }
        }
        if let Some(c) = &self.camera {
            if c.width == 0 || c.height == 0 {
                return Err(HalError::Config(format!(
                    "camera size {}x{}",
                    c.width, c.height
                )));
            }
            if !(c.min_exposure_s > 0.0 && c.max_exposure_s >= c.min_exposure_s) {
                return Err(HalError::Config(format!(
                    "camera exposure range {}..{} s",
                    c.min_exposure_s, c.max_exposure_s
                )));
            }
        }
        Ok(())
    }
}

/// A V4L2 camera delivering raw 10-bit Bayer frames.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct V4lCameraConfig {
    /// Device index (`/dev/video<index>`).
    pub index: u32,
    /// Sensor columns.
    pub width: usize,
    /// Sensor rows.
    pub height: usize,
    /// Colour filter arrangement.
    #[serde(default)]
    pub pattern: BayerPattern,
    /// Memory layout of the raw frames.
    pub pixel_format: Bayer10Format,
    /// Row stride in bytes if the driver pads rows.
    #[serde(default)]
    pub bytes_per_line: Option<usize>,
    /// Shortest exposure, seconds.
    #[serde(default = "default_min_exposure")]
    pub min_exposure_s: f64,
    /// Longest exposure, seconds.
    #[serde(default = "default_max_exposure")]
    pub max_exposure_s: f64,
    /// Unit of the V4L2 absolute exposure control, seconds (100 µs in V4L2).
    #[serde(default = "default_exposure_unit")]
    pub exposure_unit_s: f64,
    /// Sensor temperature recorded in frames, °C (V4L2 has no standard temperature control).
    #[serde(default = "default_temperature")]
    pub sensor_temperature_c: f64,
}

fn default_temperature() -> f64 {
    25.0
}

fn default_min_exposure() -> f64 {
    40e-6
}
fn default_max_exposure() -> f64 {
    60.0
}
fn default_exposure_unit() -> f64 {
    100e-6
}

/// A USB device identified by vendor and product id.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct UsbDeviceSpec {
    /// Human-readable name used in error messages.
    pub name: String,
    /// USB vendor id.
    pub vendor_id: u16,
    /// USB product id.
    pub product_id: u16,
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn example_file_parses_and_round_trips() {
        let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../docs/rig.example.toml");
        let cfg = RigConfig::load(&path).unwrap();
        assert_eq!(cfg.backend, Backend::Sim);
        assert!(cfg.motion.is_some() && cfg.camera.is_some() && cfg.sim.is_some());
        let text = cfg.to_toml_string().unwrap();
        assert_eq!(RigConfig::from_toml_str(&text).unwrap(), cfg);
    }

    #[test]
    fn inconsistent_configs_are_rejected() {
        let e = RigConfig::from_toml_str("backend = \"real\"\n").unwrap_err();
        assert!(e.to_string().contains("[motion]"), "{e}");
        let e = RigConfig::from_toml_str("backend = \"warp\"\n").unwrap_err();
        assert!(matches!(e, HalError::Config(_)));
        let e = RigConfig::from_toml_str("bogus = 1\n").unwrap_err();
        assert!(matches!(e, HalError::Config(_)));
    }
}
