//! What a job measures ([`JobSpec`]), what it writes about itself ([`JobRecord`], stored as
//! `DIR/job.json` and checked on resume) and the lamp positions.

use crate::error::{AcquireError, Result};
use binning::BinAssignment;
use serde::{Deserialize, Serialize};

/// Version of the `job.json` layout written by this crate.
pub const JOB_VERSION: u32 = 1;

pub use gantry_hal::{position_angles, LAST_POSITION_DEG, THESIS_POSITIONS};

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

/// What a job measures, whatever the devices: the material, the lamp positions, the exposure
/// strategy and the binning. With the station it runs on it determines the job's result (see
/// [`JobRecord`]).
///
/// # Examples
///
/// ```
/// use acquire::{Bracketing, JobSpec};
///
/// let spec = JobSpec::new("ggx:alpha=0.2,kd=0.1", 90);
/// spec.validate().unwrap();
/// assert_eq!(spec.angles_deg.len(), 90);
/// assert_eq!(spec.bracketing, Bracketing::Full); // the thesis's 18 exposures everywhere
/// assert!(spec.angles_deg.windows(2).all(|w| w[0] < w[1]));
/// assert!(JobSpec::new("ggx:alpha=0.2,kd=0.1", 0).validate().is_err());
///
/// // a ladder that stops at 2 s: the thesis's 15 shortest exposures
/// let mut capped = JobSpec::new("ggx:alpha=0.2,kd=0.1", 90);
/// capped.max_exposure_s = Some(2.0);
/// assert_eq!(capped.ladder().len(), 15);
/// assert!(capped.ladder().iter().all(|&t| t <= 2.0));
/// capped.max_exposure_s = Some(0.0); // shorter than any exposure
/// assert!(capped.validate().is_err());
/// ```
#[derive(Debug, Clone, PartialEq)]
pub struct JobSpec {
    /// Material spec of the sample (the simulator's sample; informative on devices).
    pub material: String,
    /// Number of lamp positions.
    pub positions: usize,
    /// Exposure strategy.
    pub bracketing: Bracketing,
    /// Whether raw frames are kept (`DIR/frames/`) for a later re-merge.
    pub keep_frames: bool,
    /// Lamp angles, degrees ([`position_angles`]).
    pub angles_deg: Vec<f64>,
    /// Which bin a BRDF sample goes to.
    pub bin_assignment: BinAssignment,
    /// Longest exposure taken, seconds: the ladder (full, or the candidates of adaptive
    /// bracketing) stops there. `None` keeps the thesis's 20 s. Pixels too dim for the
    /// shortened ladder give no samples, so a capped capture measures fewer bins in less time.
    pub max_exposure_s: Option<f64>,
}

impl JobSpec {
    /// A job measuring `material` (a material spec) at `positions` lamp positions, full
    /// bracketing, nearest-node binning.
    pub fn new(material: impl Into<String>, positions: usize) -> Self {
        Self {
            material: material.into(),
            positions,
            bracketing: Bracketing::Full,
            keep_frames: false,
            angles_deg: position_angles(positions),
            bin_assignment: BinAssignment::NearestNode,
            max_exposure_s: None,
        }
    }

    /// The exposures a position may use, seconds: the thesis's ladder up to
    /// [`max_exposure_s`](Self::max_exposure_s).
    pub fn ladder(&self) -> Vec<f64> {
        let full = hdr::thesis_ladder();
        match self.max_exposure_s {
            None => full,
            Some(cap) => full
                .into_iter()
                .filter(|&t| t <= cap * (1.0 + 1e-9))
                .collect(),
        }
    }

    /// Checks the parameters: at least one position, finite angles matching the count.
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
        if self.angles_deg.iter().any(|a| !a.is_finite()) {
            return Err(AcquireError::InvalidJob(
                "a lamp angle is not finite".into(),
            ));
        }
        if let Some(cap) = self.max_exposure_s {
            let shortest = hdr::thesis_ladder()[0];
            if !(cap.is_finite() && cap >= shortest) {
                return Err(AcquireError::InvalidJob(format!(
                    "the longest exposure must be at least the ladder's shortest, {shortest} s (got {cap})"
                )));
            }
        }
        Ok(())
    }
}

/// What a job writes about itself (`DIR/job.json`, checked on resume): its [`JobSpec`], the
/// backend, and on the simulator how the simulator was set up (sensor scale, seed, faults;
/// `1`, `1`, `false` on devices). The layout is the one every earlier version wrote, so old
/// job folders still read.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct JobRecord {
    /// Layout version ([`JOB_VERSION`]).
    pub version: u32,
    /// Simulator or devices.
    pub backend: Backend,
    /// Material spec of the sample.
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
    /// Whether raw frames are kept.
    pub keep_frames: bool,
    /// Lamp angles, degrees.
    pub angles_deg: Vec<f64>,
    /// Which bin a BRDF sample goes to. Jobs written before this field existed binned with the
    /// reference reader's indexing.
    #[serde(default = "reference_reader")]
    pub bin_assignment: BinAssignment,
    /// Longest exposure, seconds (absent: the thesis's ladder up to 20 s).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub max_exposure_s: Option<f64>,
}

fn reference_reader() -> BinAssignment {
    BinAssignment::ReferenceReader
}

impl JobRecord {
    /// The record of `spec` on devices.
    pub fn on_devices(spec: &JobSpec) -> Self {
        Self::new(spec, Backend::Rig, 1.0, 1, false)
    }

    /// The record of `spec` on `backend`, with the simulator's sensor scale, seed and faults.
    pub fn new(spec: &JobSpec, backend: Backend, scale: f64, seed: u64, faults: bool) -> Self {
        let JobSpec {
            material,
            positions,
            bracketing,
            keep_frames,
            angles_deg,
            bin_assignment,
            max_exposure_s,
        } = spec.clone();
        Self {
            version: JOB_VERSION,
            backend,
            material,
            positions,
            scale,
            seed,
            faults,
            bracketing,
            keep_frames,
            angles_deg,
            bin_assignment,
            max_exposure_s,
        }
    }

    /// What the recorded job measures.
    pub fn spec(&self) -> JobSpec {
        JobSpec {
            material: self.material.clone(),
            positions: self.positions,
            bracketing: self.bracketing,
            keep_frames: self.keep_frames,
            angles_deg: self.angles_deg.clone(),
            bin_assignment: self.bin_assignment,
            max_exposure_s: self.max_exposure_s,
        }
    }
}
