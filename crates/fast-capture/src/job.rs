//! The fast capture as a job: plan (or read the stored plan), capture the planned positions with
//! `acquire`, complete the table from the model, write the files and the report.

use crate::complete::{complete, Completion, Residual};
use crate::coverage::Coverage;
use crate::error::{io, FastError, Result};
use crate::plan::{plan, CapturePlan, PlanOptions, PLAN_VERSION};
use acquire::{CalibrationSource, JobSpec, Outcome, RunOptions, Station, TableError};
use binning::SphereView;
use brdf::MerlTable;
use serde::{Deserialize, Serialize};
use std::path::{Path, PathBuf};
use std::time::Instant;

/// Files of a fast capture in its directory `DIR`.
///
/// ```text
/// DIR/plan.json            the plan (positions, exposures, predicted clock, why each position)
/// DIR/capture/             the capture job of the planned positions (acquire's layout;
///                          capture/brdf.binary holds the measured entries only)
/// DIR/brdf.binary          the completed table (MERL format)
/// DIR/measured.npy         float32 [3, BINS]: 1 where the entry was measured, 0 where completed
/// DIR/completion_sd.npy    float32 [3, BINS]: standard deviation of a completed entry's log value
/// DIR/fast_report.json     the report (FastReport)
/// ```
#[derive(Debug, Clone)]
pub struct FastDir {
    root: PathBuf,
}

impl FastDir {
    /// The files under `root`.
    pub fn new(root: impl Into<PathBuf>) -> Self {
        Self { root: root.into() }
    }
    /// `plan.json`.
    pub fn plan(&self) -> PathBuf {
        self.root.join("plan.json")
    }
    /// `capture/`, the capture job's directory.
    pub fn capture(&self) -> PathBuf {
        self.root.join("capture")
    }
    /// `brdf.binary`, the completed table.
    pub fn table(&self) -> PathBuf {
        self.root.join("brdf.binary")
    }
    /// `measured.npy`.
    pub fn measured(&self) -> PathBuf {
        self.root.join("measured.npy")
    }
    /// `completion_sd.npy`.
    pub fn completion_sd(&self) -> PathBuf {
        self.root.join("completion_sd.npy")
    }
    /// `fast_report.json`.
    pub fn report(&self) -> PathBuf {
        self.root.join("fast_report.json")
    }
}

/// How a fast capture runs.
#[derive(Debug, Clone, Default)]
pub struct FastOptions {
    /// What the planner may spend.
    pub plan: PlanOptions,
    /// How the capture job runs (calibration, lamp constant, resume, progress...).
    pub run: RunOptions,
    /// Plan only: return the plan, write nothing and touch no device beyond reading it.
    pub dry_run: bool,
    /// What the completion does with the model's misfit at the measured entries.
    pub residual: Residual,
}

/// Errors of a table against the truth over the entries a full capture reaches.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Scores {
    /// Median over the entries of |ln(f̂ / f)|.
    pub median_abs_log: f64,
    /// Cosine-weighted relative RMS ([`brdf::metrics::cosine_weighted_relative_rms`]).
    pub cosine_weighted_relative_rms: f64,
}

/// On the simulator: the fast table and the model's floor against the true table.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct TruthScores {
    /// Entries compared (those a full capture reaches, true value known).
    pub entries: usize,
    /// The completed table.
    pub fast: Scores,
    /// The projection of the true table on the same components: what a perfect completion of
    /// a table the model had to explain everywhere would give.
    pub floor: Scores,
    /// The measured entries alone (the capture's table) over the entries they cover.
    pub measured: TableError,
}

/// `DIR/fast_report.json`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct FastReport {
    /// Material spec of the sample.
    pub material: String,
    /// Lamp positions captured.
    pub positions: usize,
    /// Their angles, degrees.
    pub angles_deg: Vec<f64>,
    /// The plan's predicted clock, seconds.
    pub predicted_clock_s: f64,
    /// The simulated rig's clock of the capture, seconds (simulator only).
    pub simulated_capture_s: Option<f64>,
    /// Components of the model used.
    pub components: usize,
    /// Entries (channel, bin) measured.
    pub measured_entries: usize,
    /// Entries completed from the model.
    pub completed_entries: usize,
    /// Entries a full capture over every candidate position reaches.
    pub full_entries: usize,
    /// Share of those that this capture measured.
    pub measured_share_of_full: f64,
    /// Median over completed entries of the standard deviation of their log value.
    pub completion_log_sd_median: f64,
    /// On the simulator: errors against the true table.
    pub truth: Option<TruthScores>,
    /// Wall-clock seconds of the whole job.
    pub wall_s: f64,
}

/// How [`run`] ended.
#[derive(Debug, Clone)]
pub enum FastOutcome {
    /// A dry run: the plan.
    Planned(Box<CapturePlan>),
    /// The completed table is written.
    Finished(Box<FastReport>),
    /// The capture stopped as asked ([`RunOptions::stop_after`]); resume to continue.
    Stopped {
        /// Positions captured by this run.
        new_positions: usize,
    },
}

/// The geometry the plan is made for: the calibration file when one is given, otherwise (on
/// the simulator) its true geometry.
fn planning_geometry(station: &Station, run: &RunOptions) -> Result<calib::Calibration> {
    match (&run.calibration, &station.simulator) {
        (CalibrationSource::File(p), _) => {
            calib::Calibration::read(p).map_err(|e| FastError::Acquire(e.into()))
        }
        (_, Some(sim)) => Ok(sim.true_calibration()?),
        (_, None) => Err(FastError::InvalidOption(
            "on devices the plan needs the rig's calibration file (calibrate the rig first)".into(),
        )),
    }
}

/// Plans a fast capture on `station` for `model` (no file is written).
pub fn plan_capture(
    station: &Station,
    spec: &JobSpec,
    model: &reduce::Model,
    options: &FastOptions,
) -> Result<CapturePlan> {
    let coverage = candidate_coverage(station, spec, &options.run, options.plan.candidates)?;
    plan(model, &coverage, &options.plan)
}

/// The entries each of `candidates` evenly spaced lamp angles reaches on `station`, seen with
/// the planning geometry ([`planning_geometry`]) and the camera's Bayer pattern.
fn candidate_coverage(
    station: &Station,
    spec: &JobSpec,
    run: &RunOptions,
    candidates: usize,
) -> Result<Coverage> {
    let calibration = planning_geometry(station, run)?;
    let pattern = station.rig.camera.info().pattern;
    let view = SphereView::new(&calibration, move |x, y| pattern.channel_at(x, y), 85.0);
    let angles = gantry_hal::position_angles(candidates);
    Coverage::compute(&view, &calibration, &angles, spec.bin_assignment)
}

fn read_plan(path: &Path) -> Result<CapturePlan> {
    let bytes = std::fs::read(path).map_err(io(path))?;
    let plan: CapturePlan = serde_json::from_slice(&bytes).map_err(|e| FastError::Malformed {
        path: path.to_path_buf(),
        reason: e.to_string(),
    })?;
    if plan.version != PLAN_VERSION {
        return Err(FastError::Malformed {
            path: path.to_path_buf(),
            reason: format!(
                "plan version {} (this build reads {PLAN_VERSION})",
                plan.version
            ),
        });
    }
    if plan.angles_deg.is_empty() || plan.angles_deg.iter().any(|a| !a.is_finite()) {
        return Err(FastError::Malformed {
            path: path.to_path_buf(),
            reason: "no lamp position, or one that is not finite".into(),
        });
    }
    plan.options.validate()?;
    Ok(plan)
}

fn write_npy(path: &Path, values: &[f32]) -> Result<()> {
    let bytes = brdf::npy::to_bytes(&[3, brdf::BINS], values);
    atomic_write::write_atomic(path, &bytes).map_err(io(path))
}

/// `truth` with every entry outside `mask` missing.
fn masked(truth: &MerlTable, mask: &[bool]) -> Result<MerlTable> {
    let v: Vec<f64> = truth
        .values()
        .iter()
        .zip(mask)
        .map(|(&t, &m)| if m { t } else { -1.0 })
        .collect();
    Ok(MerlTable::from_values(v)?)
}

/// Scores of `estimate` against `truth` (already restricted to the compared entries).
pub fn scores(truth: &MerlTable, estimate: &MerlTable) -> Scores {
    Scores {
        median_abs_log: acquire::table_error(estimate, truth).median_abs_log,
        cosine_weighted_relative_rms: brdf::metrics::cosine_weighted_relative_rms(truth, estimate),
    }
}

/// The truth comparison of a finished fast capture on the simulator.
fn truth_scores(
    material: &str,
    model: &reduce::Model,
    k: usize,
    reached: &[bool],
    measured: &MerlTable,
    completed: &MerlTable,
) -> Result<TruthScores> {
    let truth = brdf::load(material)?.tabulate();
    let compared = masked(&truth, reached)?;
    let floor = model.reconstruct(&truth, k)?;
    Ok(TruthScores {
        entries: compared.values().iter().filter(|v| **v >= 0.0).count(),
        fast: scores(&compared, completed),
        floor: scores(&compared, &floor),
        measured: acquire::table_error(measured, &truth),
    })
}

/// Runs a fast capture of `spec.material` into `dir` (layout: [`FastDir`]).
///
/// A new job plans its positions ([`plan_capture`]) and stores the plan before the first
/// position; a resumed one ([`RunOptions::resume`]) reads the stored plan, so that it captures
/// the same positions. The capture itself is an `acquire` job of the planned angles and
/// exposures in `DIR/capture` (`spec`'s material, bracketing, binning and frames are kept; its
/// angles and longest exposure come from the plan), resumable like every job. Its measured
/// entries are then completed from `model` ([`complete`]).
pub fn run(
    station: &mut Station,
    spec: &JobSpec,
    model: &reduce::Model,
    options: &FastOptions,
    dir: &Path,
) -> Result<FastOutcome> {
    let started = Instant::now();
    let files = FastDir::new(dir);
    let stored = files.plan().exists();
    let plan = if options.dry_run {
        return Ok(FastOutcome::Planned(Box::new(plan_capture(
            station, spec, model, options,
        )?)));
    } else if stored && options.run.resume {
        let plan = read_plan(&files.plan())?;
        if plan.model_materials != model.pca.coords.nrows() {
            return Err(FastError::PlanMismatch {
                path: files.plan(),
                reason: format!(
                    "planned for a model of {} materials, this model has {}",
                    plan.model_materials,
                    model.pca.coords.nrows()
                ),
            });
        }
        plan
    } else if stored {
        return Err(FastError::InvalidOption(format!(
            "{} already holds a fast capture: resume it, or choose another directory",
            dir.display()
        )));
    } else {
        let plan = plan_capture(station, spec, model, options)?;
        std::fs::create_dir_all(dir).map_err(io(dir))?;
        acquire::write_json(&files.plan(), &plan)?;
        plan
    };
    let capture_spec = JobSpec {
        positions: plan.angles_deg.len(),
        angles_deg: plan.angles_deg.clone(),
        max_exposure_s: plan.options.max_exposure_s,
        ..spec.clone()
    };
    let mut run_options = options.run.clone();
    run_options.resume = run_options.resume || files.capture().join("job.json").exists();
    let done = match acquire::run(station, &capture_spec, &run_options, files.capture())? {
        Outcome::Finished(done) => done,
        Outcome::Stopped { new_positions } => return Ok(FastOutcome::Stopped { new_positions }),
        Outcome::LampConstant(_) => {
            return Err(FastError::InvalidOption(
                "a white-reference run measures the lamp constant: run it as a plain capture"
                    .into(),
            ))
        }
    };
    let measured = brdf::merl::read(acquire::JobDir::new(files.capture()).table())?;
    let k = plan.options.components.min(model.pca.components);
    let Completion {
        table,
        measured: mask,
        log_sd,
        measured_entries,
        ..
    } = complete(model, &measured, k, options.residual)?;
    brdf::merl::write(files.table(), &table)?;
    let flags: Vec<f32> = mask.iter().map(|&m| if m { 1.0 } else { 0.0 }).collect();
    write_npy(&files.measured(), &flags)?;
    write_npy(&files.completion_sd(), &log_sd)?;
    // The entries a full capture reaches, for the report's shares and truth scores.
    let reached = candidate_coverage(station, spec, &options.run, plan.options.candidates)?.union();
    let full_entries = reached.iter().filter(|&&r| r).count();
    let measured_in_full = reached.iter().zip(&mask).filter(|(&r, &m)| r && m).count();
    let mut sds: Vec<f32> = log_sd
        .iter()
        .zip(&mask)
        .filter(|(_, &m)| !m)
        .map(|(&s, _)| s)
        .collect();
    sds.sort_by(f32::total_cmp);
    let truth = match station.simulator {
        Some(_) => Some(truth_scores(
            &spec.material,
            model,
            k,
            &reached,
            &measured,
            &table,
        )?),
        None => None,
    };
    let report = FastReport {
        material: spec.material.clone(),
        positions: plan.angles_deg.len(),
        angles_deg: plan.angles_deg.clone(),
        predicted_clock_s: plan.predicted_clock_s,
        simulated_capture_s: done.report.simulated_capture_s,
        components: k,
        measured_entries,
        completed_entries: mask.len() - measured_entries,
        full_entries,
        measured_share_of_full: measured_in_full as f64 / full_entries.max(1) as f64,
        completion_log_sd_median: sds.get(sds.len() / 2).copied().unwrap_or(0.0) as f64,
        truth,
        wall_s: started.elapsed().as_secs_f64(),
    };
    acquire::write_json(&files.report(), &report)?;
    Ok(FastOutcome::Finished(Box::new(report)))
}
