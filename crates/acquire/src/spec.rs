//! What a job measures: the parameters that determine its result ([`JobSpec`], stored as
//! `DIR/job.json` and checked on resume) and the lamp positions.

use crate::error::{AcquireError, Result};
use binning::BinAssignment;
use serde::{Deserialize, Serialize};

/// Version of the `job.json` layout written by this crate.
pub const JOB_VERSION: u32 = 1;

pub use gantry_hal::positions::{position_angles, LAST_POSITION_DEG, THESIS_POSITIONS};

/// Where the frames come from.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Backend {
    /// The simulated rig of `hal-sim` (the true material is known, so the report gives the
    /// table's error against it).
    Sim,
    /// Devices opened by the caller (real hardware, or a simulated rig driven like hardware).
    Rig,
}

/// Exposure strategy.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Bracketing {
    /// The thesis's 18 exposures, 40 µs to 20 s, at every position.
    Full,
    /// Exposures chosen from the previous position's radiance range.
    Adaptive,
}

/// The parameters that determine a job's result; stored as `DIR/job.json`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct JobSpec {
    /// Layout version ([`JOB_VERSION`]).
    pub version: u32,
    /// Simulator or devices.
    pub backend: Backend,
    /// Material spec of the simulated sample (informative on devices).
    pub material: String,
    /// Number of lamp positions.
    pub positions: usize,
    /// Sensor scale of the simulated camera (1 = 1300 × 1030).
    pub scale: f64,
    /// Seed of the simulator's noise and faults.
    pub seed: u64,
    /// Whether the simulator injects faults.
    pub faults: bool,
    /// Exposure strategy.
    pub bracketing: Bracketing,
    /// Whether raw frames are kept (`DIR/frames/`) for a later re-merge.
    pub keep_frames: bool,
    /// Lamp angles, degrees ([`position_angles`]).
    pub angles_deg: Vec<f64>,
    /// Which bin a BRDF sample goes to. Jobs written before this field existed binned with the
    /// reference reader's indexing.
    #[serde(default = "reference_reader")]
    pub bin_assignment: BinAssignment,
}

fn reference_reader() -> BinAssignment {
    BinAssignment::ReferenceReader
}

impl JobSpec {
    /// A job on the simulated rig measuring `material` (a material spec) at `positions` lamp
    /// positions, full sensor, seed 1, no faults, full bracketing, nearest-node binning.
    pub fn simulated(material: impl Into<String>, positions: usize) -> Self {
        Self {
            version: JOB_VERSION,
            backend: Backend::Sim,
            material: material.into(),
            positions,
            scale: 1.0,
            seed: 1,
            faults: false,
            bracketing: Bracketing::Full,
            keep_frames: false,
            angles_deg: position_angles(positions),
            bin_assignment: BinAssignment::NearestNode,
        }
    }

    /// A job on devices the caller opens.
    pub fn on_devices(material: impl Into<String>, positions: usize) -> Self {
        Self {
            backend: Backend::Rig,
            ..Self::simulated(material, positions)
        }
    }

    /// The same job at sensor scale `scale`.
    pub fn with_scale(mut self, scale: f64) -> Self {
        self.scale = scale;
        self
    }

    /// Checks the parameters: at least one position, angles matching the count, a scale in
    /// (0, 1].
    pub fn validate(&self) -> Result<()> {
        if self.positions == 0 {
            return Err(AcquireError::InvalidJob(
                "at least one lamp position is needed".into(),
            ));
        }
        if self.angles_deg.len() != self.positions {
            return Err(AcquireError::InvalidJob(format!(
                "{} angles for {} positions",
                self.angles_deg.len(),
                self.positions
            )));
        }
        if !(self.scale > 0.0 && self.scale <= 1.0) {
            return Err(AcquireError::InvalidJob(format!(
                "sensor scale must be in (0, 1], got {}",
                self.scale
            )));
        }
        if self.angles_deg.iter().any(|a| !a.is_finite()) {
            return Err(AcquireError::InvalidJob(
                "a lamp angle is not finite".into(),
            ));
        }
        Ok(())
    }

    /// The simulator configuration of this job (its material, scale, seed and faults).
    pub fn sim_config(&self) -> hal_sim::SimConfig {
        let mut cfg = hal_sim::SimConfig::with_scale(self.scale);
        cfg.seed = self.seed;
        cfg.material = self.material.clone();
        if self.faults {
            cfg.faults = hal_sim::FaultConfig {
                seed: self.seed ^ 0x5eed,
                turntable_timeout: 0.01,
                camera_frame_drop: 0.01,
                lamp_dropout: 0.003,
                ..cfg.faults
            };
        }
        cfg
    }
}
