//! # acquire — the BRDF measurement job
//!
//! The lab operator's job of thesis chapter 3 as a library: calibration → dark frame → lamp-off
//! ambient → lamp constant → at every lamp position: move, bracketed exposures, HDR merge and its
//! consistency checks, BRDF samples → robust binning → validation by re-rendering → report.
//! Every finished position is a checkpoint on disk (written atomically), so a job that was
//! killed resumes and ends with the same bytes. Device faults are handled by a retry policy
//! (`devices`) and reported as typed [`FaultEvent`]s.
//!
//! A small measurement of an analytic material on the simulated rig:
//!
//! ```
//! # #[cfg(feature = "sim")] {
//! use acquire::{CalibrationSource, JobSpec, Outcome, RunOptions, SimSetup, Station};
//! let dir = tempfile::tempdir()?;
//! let spec = JobSpec::new("ggx:alpha=0.3,kd=0.2/0.1/0.05,ks=0.04", 3);
//! let mut station = Station::simulated(&spec, &SimSetup::with_scale(0.1))?;
//! let options = RunOptions {
//!     calibration: CalibrationSource::TrueGeometry,
//!     ..RunOptions::default()
//! };
//! let Outcome::Finished(done) = acquire::run(&mut station, &spec, &options, dir.path())? else {
//!     unreachable!("no stop was asked for");
//! };
//! let error = done.report.truth_table_error.as_ref().expect("the simulator knows the truth");
//! assert!(done.report.coverage > 0.0 && error.median_abs_log < 0.2);
//! assert!(dir.path().join("brdf.binary").exists());
//! # }
//! # Ok::<(), Box<dyn std::error::Error>>(())
//! ```
//!
//! The job follows thesis chapter 3 (§3.1–3.6) in this order:
//!
//! 1. [`JobSpec`] says what is measured (material, lamp positions, [`Bracketing`], bin
//!    assignment); its [`JobRecord`] is `DIR/job.json`, checked on resume. [`JobDir`] knows where
//!    every file of the job directory lives.
//! 2. A [`Station`] holds the devices (a real rig, or with feature `sim` the simulated one of
//!    [`SimSetup`], whose [`GroundTruth`] knows the true material and geometry); [`Devices`]
//!    wraps them in the retry policy, which logs every fault it handles as a [`FaultEvent`].
//! 3. [`run()`] runs the stages of [`JobStage::ALL`] in order, each through [`load_or_compute`]:
//!    geometry ([`CalibrationSource`], thesis §3.2), dark frame, lamp-off ambient, lamp
//!    constant, then every lamp position (move, bracketed exposures, HDR merge and its
//!    consistency checks, BRDF samples; thesis §3.3–3.4, logged as a [`PositionLog`]), binning
//!    and validation (thesis §3.6) and, when asked for, the inverse mapping (thesis §3.5).
//!    [`RunOptions`] holds what may change between runs; the [`Outcome`] is a finished job, a
//!    stop, or a lamp constant.
//! 4. The [`Report`] (`DIR/report.json`) has the timings, sample counts, coverage, validation
//!    and faults, and on the simulator the [`TableError`] against the truth. [`rebin()`] runs
//!    the stages after the capture again from the stored positions.

#![warn(missing_docs)]

mod devices;
mod error;
mod finish;
mod job;
mod layout;
mod position;
mod report;
mod setup;
#[cfg(feature = "sim")]
mod sim;
mod spec;

pub use finish::Truth;
pub use layout::{read_json, write_json, HotPixels};
pub use report::{FaultSummary, PositionFault, PositionValidation};
pub use spec::{JOB_VERSION, LAST_POSITION_DEG, THESIS_POSITIONS};

pub use brdf::metrics::{table_error, TableError};
pub use devices::{Devices, FaultEvent, FaultKind};
pub use error::{AcquireError, Result};
pub use job::{load_or_compute, JobStage};
pub use layout::{JobDir, JobLock, PositionCheck};
pub use position::{PositionContext, PositionLog, PositionTimings};
pub use report::{reciprocal_table, InverseReport, Report, Stages};
pub use setup::{CalibrationSource, GroundTruth, Station};
#[cfg(feature = "sim")]
pub use sim::{SimSetup, SimulatedRig, SIM_WHITE_ALBEDO};
pub use spec::{position_angles, Backend, Bracketing, JobRecord, JobSpec};

use job::{Job, JobStart};
use std::path::{Path, PathBuf};
use std::sync::Arc;

/// A stage of the job, for progress reports.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Stage {
    /// Lamp positions being captured (`done` of `total`; positions finished before a resume
    /// count as done).
    Positions,
    /// Binning the samples.
    Binning,
    /// Re-rendering the positions.
    Validation,
    /// The inverse mapping.
    Inverse,
}

/// A progress report: `done` of `total` units of `stage`.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Progress {
    /// What the job is doing.
    pub stage: Stage,
    /// Units finished.
    pub done: usize,
    /// Units in all.
    pub total: usize,
}

/// Called as the job advances.
pub type ProgressFn = Arc<dyn Fn(&Progress) + Send + Sync>;

/// How a job runs (what does not change its result).
#[derive(Clone)]
pub struct RunOptions {
    /// Where the geometry comes from (a calibration already stored in the job directory wins
    /// over [`CalibrationSource::Calibrate`] and [`CalibrationSource::TrueGeometry`] on resume).
    pub calibration: CalibrationSource,
    /// The lamp constant file of a white-standard run; required on devices, measured with a
    /// simulated white standard on the simulator when absent.
    pub lamp_constant: Option<PathBuf>,
    /// Measure only the lamp constant, with a diffuse white standard of this albedo mounted in
    /// place of the sample ([`Outcome::LampConstant`]; writes `DIR/lamp_constant.json`).
    pub white_reference: Option<f64>,
    /// Continue a job whose directory already exists (its `job.json` must match).
    pub resume: bool,
    /// Simulator only: write the noise-free signal rate per position (`DIR/truth/NNN.exr`).
    pub save_truth: bool,
    /// Memory budget of the job, MiB: binning's value buffers get what is left after the
    /// memory the job has added to the process when binning starts (what the process held
    /// before [`run`] is not counted) and binning's fixed tables, so that the job's peak stays
    /// within it.
    pub memory_mb: usize,
    /// Also fill the table by the inverse mapping (thesis §3.5).
    pub inverse: bool,
    /// Stop after this many new positions ([`Outcome::Stopped`]).
    pub stop_after: Option<usize>,
    /// Called after every position and stage.
    pub progress: Option<ProgressFn>,
}

impl Default for RunOptions {
    fn default() -> Self {
        Self {
            calibration: CalibrationSource::Calibrate,
            lamp_constant: None,
            white_reference: None,
            resume: false,
            save_truth: false,
            memory_mb: 512,
            inverse: false,
            stop_after: None,
            progress: None,
        }
    }
}

impl std::fmt::Debug for RunOptions {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("RunOptions")
            .field("calibration", &self.calibration)
            .field("lamp_constant", &self.lamp_constant)
            .field("white_reference", &self.white_reference)
            .field("resume", &self.resume)
            .field("save_truth", &self.save_truth)
            .field("memory_mb", &self.memory_mb)
            .field("inverse", &self.inverse)
            .field("stop_after", &self.stop_after)
            .finish()
    }
}

impl RunOptions {
    fn report(&self, stage: Stage, done: usize, total: usize) {
        if let Some(p) = &self.progress {
            p(&Progress { stage, done, total });
        }
    }
}

/// A finished job.
#[derive(Debug, Clone)]
pub struct Finished {
    /// `DIR/report.json`.
    pub report: Report,
    /// `DIR/inverse_report.json`, when the inverse mapping ran.
    pub inverse: Option<InverseReport>,
}

/// How [`run`] ended.
#[derive(Debug, Clone)]
pub enum Outcome {
    /// The table is measured.
    Finished(Box<Finished>),
    /// Stopped as [`RunOptions::stop_after`] asked, after this many new positions; resume to
    /// continue.
    Stopped {
        /// Positions captured by this run.
        new_positions: usize,
    },
    /// A white-standard run measured the lamp constant (per channel), written to
    /// `DIR/lamp_constant.json`.
    LampConstant([f64; 3]),
}

/// Runs (or resumes) the measurement `spec` on `station`, writing into `dir`: the stages of
/// [`JobStage::ALL`] in order, each loading its checkpoint or computing it.
pub fn run(
    station: &mut Station,
    spec: &JobSpec,
    options: &RunOptions,
    dir: impl AsRef<Path>,
) -> Result<Outcome> {
    let start = JobStart::now();
    spec.validate()?;
    let dir = JobDir::new(dir.as_ref());
    // One job per directory: a second process is refused, a killed job's lock is taken over.
    let _lock = layout::JobLock::acquire(&dir)?;
    dir.remove_temporaries();
    // The job directory: a new job, or the same job resumed.
    let record = station.record(spec);
    if dir.job().exists() {
        if !options.resume {
            return Err(AcquireError::JobDirectory {
                path: dir.root().to_path_buf(),
                reason: "already holds a capture: resume it, or choose another directory".into(),
            });
        }
        if layout::read_json::<JobRecord>(&dir.job())? != record {
            return Err(AcquireError::JobDirectory {
                path: dir.job(),
                reason: "resumed with different parameters than the interrupted job".into(),
            });
        }
    } else {
        layout::write_json(&dir.job(), &record)?;
    }
    dir.create()?;
    let mut job = Job::new(dir, record, options, start, Some(station));
    for stage in JobStage::ALL {
        if let Some(outcome) = job.stage(stage)? {
            return Ok(outcome);
        }
    }
    Ok(Outcome::Finished(Box::new(job.finished()?)))
}

/// Re-runs HDR (from the frames a capture kept) and binning, validation and report of the
/// capture in `dir`, without the devices: the binning's and the report's checkpoints are
/// deleted and [`JobStage::RESULTS`] run again. `options` supplies the memory budget, the
/// inverse mapping and progress; the rest of it is ignored.
pub fn rebin(dir: impl AsRef<Path>, options: &RunOptions) -> Result<Finished> {
    let start = JobStart::now();
    let dir = JobDir::new(dir.as_ref());
    let _lock = layout::JobLock::acquire(&dir)?;
    let record: JobRecord = layout::read_json(&dir.job())?;
    record.spec().validate()?;
    let pattern = camera_pattern(&record)?;
    for stage in JobStage::RESULTS {
        let checkpoint = stage.checkpoint(&dir);
        if checkpoint.exists() {
            std::fs::remove_file(&checkpoint).map_err(error::io(&checkpoint))?;
        }
    }
    let mut job = Job::new(dir, record, options, start, None).captured(pattern)?;
    job.remerge()?;
    for stage in JobStage::RESULTS {
        job.stage(stage)?;
    }
    job.finished()
}

/// The Bayer pattern of the camera a recorded job ran on.
fn camera_pattern(record: &JobRecord) -> Result<gantry_hal::BayerPattern> {
    match record.backend {
        #[cfg(feature = "sim")]
        Backend::Sim => sim::SimSetup::of_record(record)
            .ok_or_else(|| AcquireError::InvalidJob("no simulator setup".into()))?
            .pattern(&record.material),
        #[cfg(not(feature = "sim"))]
        Backend::Sim => Err(AcquireError::InvalidJob(
            "a simulated capture needs acquire's feature 'sim' to re-bin".into(),
        )),
        Backend::Rig => Ok(gantry_hal::BayerPattern::Rggb),
    }
}
