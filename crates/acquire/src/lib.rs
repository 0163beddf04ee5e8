//! # acquire — the BRDF measurement job
//!
//! The lab operator's job of thesis chapter 3 as a library: calibration → dark frame → lamp-off
//! ambient → lamp constant → at every lamp position: move, bracketed exposures, HDR merge and its
//! consistency checks, BRDF samples → robust binning → validation by re-rendering → report.
//! Every finished position is a checkpoint on disk (written atomically), so a job that was
//! killed resumes and ends with the same bytes. Device faults are handled by a retry policy
//! ([`devices`]) and reported as typed [`FaultEvent`]s.
//!
//! A small measurement of an analytic material on the simulated rig:
//!
//! ```
//! use acquire::{CalibrationSource, JobSpec, Outcome, RunOptions, Station};
//! let dir = tempfile::tempdir()?;
//! let spec = JobSpec::simulated("ggx:alpha=0.3,kd=0.2/0.1/0.05,ks=0.04", 3).with_scale(0.1);
//! let mut station = Station::simulated(&spec)?;
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
//! # Ok::<(), Box<dyn std::error::Error>>(())
//! ```
//!
//! The modules follow the job: [`spec`] (what is measured, `job.json`), [`layout`] (the job
//! directory), [`setup`] (devices, geometry, dark frame, ambient, lamp constant), [`devices`]
//! (the retry policy), [`position`] (one lamp position), [`finish`] (binning, validation,
//! report, inverse mapping) and [`report`].

#![warn(missing_docs)]

pub mod devices;
pub mod error;
pub mod finish;
pub mod layout;
pub mod position;
pub mod report;
pub mod setup;
pub mod spec;

pub use devices::{Devices, FaultEvent, FaultKind};
pub use error::{AcquireError, Result};
pub use layout::{JobDir, JobLock, PositionCheck};
pub use position::{PositionContext, PositionLog, PositionTimings};
pub use report::{reciprocal_table, table_error, InverseReport, Report, Stages, TableError};
pub use setup::{CalibrationSource, Station};
pub use spec::{position_angles, Backend, Bracketing, JobSpec};

use binning::{ForwardOptions, SphereView};
use hdr::HdrImage;
use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::time::Instant;

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

/// Runs (or resumes) the measurement `spec` on `station`, writing into `dir`.
pub fn run(
    station: &mut Station,
    spec: &JobSpec,
    options: &RunOptions,
    dir: impl AsRef<Path>,
) -> Result<Outcome> {
    let start = JobStart::now();
    let t_start = start.time;
    spec.validate()?;
    let dir = JobDir::new(dir.as_ref());
    if spec.backend == Backend::Sim && station.sim.is_none() {
        return Err(AcquireError::InvalidJob(
            "a simulator job needs a simulated station (Station::simulated)".into(),
        ));
    }
    // One job per directory: a second process is refused, a killed job's lock is taken over.
    let _lock = layout::JobLock::acquire(&dir)?;
    dir.remove_temporaries();
    let Station { rig, sim } = station;
    let sim = sim.as_ref();
    // The job directory: a new job, or the same job resumed.
    if dir.job().exists() {
        if !options.resume {
            return Err(AcquireError::JobDirectory {
                path: dir.root().to_path_buf(),
                reason: "already holds a capture: resume it, or choose another directory".into(),
            });
        }
        let old: JobSpec = layout::read_json(&dir.job())?;
        if &old != spec {
            return Err(AcquireError::JobDirectory {
                path: dir.job(),
                reason: "resumed with different parameters than the interrupted job".into(),
            });
        }
    } else {
        layout::write_json(&dir.job(), spec)?;
    }
    dir.create()?;
    // Geometry.
    let (calibration, geometry) = if let CalibrationSource::File(p) = &options.calibration {
        (
            calib::Calibration::read(p)?,
            format!("file {}", p.display()),
        )
    } else if dir.calibration().exists() {
        let g = layout::read_json::<serde_json::Value>(&dir.calibration())?
            .get("fit")
            .map_or("simulator truth", |_| "calibrated");
        (calib::Calibration::read(&dir.calibration())?, g.to_string())
    } else {
        match (sim, &options.calibration) {
            (Some(sim), CalibrationSource::TrueGeometry) => (
                calib::sim::calibration_from_truth(sim.truth())?,
                "simulator truth".to_string(),
            ),
            (Some(_), _) => {
                let run = setup::calibrate_simulated(spec.sim_config(), spec.seed)?;
                tracing::info!(
                    rms_px = run.reprojection_rms(),
                    "calibrated the simulated rig"
                );
                let dropped = run.dropped_views();
                if !dropped.is_empty() {
                    tracing::warn!(
                        ?dropped,
                        "target images dropped from the calibration (board not found whole)"
                    );
                }
                (run.calibration, "calibrated".to_string())
            }
            (None, _) => {
                return Err(AcquireError::InvalidJob(
                    "on devices a calibration file is needed (calibrate the rig first)".into(),
                ))
            }
        }
    };
    calibration.write(&dir.calibration())?;
    tracing::info!(%geometry, "geometry");
    let info = rig.camera.info();
    if (info.width, info.height) != (calibration.camera.width, calibration.camera.height) {
        return Err(AcquireError::InvalidJob(format!(
            "the camera delivers {}x{} frames but the calibration is for {}x{}",
            info.width, info.height, calibration.camera.width, calibration.camera.height
        )));
    }
    let pattern = info.pattern;
    let view = SphereView::new(&calibration, move |x, y| pattern.channel_at(x, y), 85.0);
    tracing::info!(pixels = view.pixels.len(), "sphere pixels");
    // Faults met before the first position (homing) go into its log.
    let mut setup_faults = Vec::new();
    Devices {
        rig: &mut *rig,
        log: &mut setup_faults,
    }
    .home()?;
    // Dark frame and defect map.
    let defects = if dir.defects().exists() {
        layout::HotPixels::read_map(&dir.defects())?
    } else {
        let map = setup::dark_frame_defects(rig)?;
        layout::write_json(&dir.defects(), &layout::HotPixels::of(&map))?;
        map
    };
    // Ambient signal (room light and dark current) with the lamp off.
    let ambient = if dir.ambient().exists() {
        layout::read_json::<[f64; 3]>(&dir.ambient())?
    } else {
        let a = setup::lamp_off_ambient(rig, &view, &defects)?;
        layout::write_json(&dir.ambient(), &a)?;
        a
    };
    tracing::info!(?ambient, "ambient rate with the lamp off, DN/s");
    rig.lamp.set_on(true)?;
    rig.lamp.wait_stable(devices::LAMP_TIMEOUT)?;
    if let Some(albedo) = options.white_reference {
        // The operator has mounted a diffuse white standard: measure the lamp constant only.
        let k = setup::white_reference(rig, &calibration, &view, &defects, albedo, sim)?;
        layout::write_json(&dir.lamp_constant(), &k)?;
        return Ok(Outcome::LampConstant(k));
    }
    // Absolute scale: a given lamp constant, the one stored by an interrupted job, or (simulator
    // only) a white-standard run now.
    let lamp_constant = if let Some(f) = &options.lamp_constant {
        let k = layout::read_lamp_constant(f)?;
        layout::write_json(&dir.lamp_constant(), &k)?;
        k
    } else if dir.lamp_constant().exists() {
        layout::read_lamp_constant(&dir.lamp_constant())?
    } else if sim.is_some() {
        let k = setup::white_reference_sim(spec, &calibration, &view, &defects)?;
        layout::write_json(&dir.lamp_constant(), &k)?;
        k
    } else {
        return Err(AcquireError::InvalidJob(
            "on devices a lamp constant file is needed (from a white-standard run)".into(),
        ));
    };
    // The black level matters only to adaptive bracketing.
    let black = match spec.bracketing {
        Bracketing::Adaptive => setup::black_level(rig)?,
        Bracketing::Full => 0.0,
    };
    let ctx = PositionContext {
        view: &view,
        calibration: &calibration,
        defects: &defects,
        lamp_constant,
        assignment: spec.bin_assignment,
        ambient: Some(ambient),
    };
    let setup_s = t_start.elapsed().as_secs_f64();
    // Positions.
    let t_capture = Instant::now();
    let n = spec.angles_deg.len();
    let mut previous: Option<HdrImage> = None;
    let mut new_positions = 0usize;
    for (i, &angle) in spec.angles_deg.iter().enumerate() {
        let mut faults = Vec::new();
        match dir.check_position(i) {
            layout::PositionCheck::Done => {
                previous = None;
                options.report(Stage::Positions, i + 1, n);
                continue;
            }
            layout::PositionCheck::Missing => {}
            layout::PositionCheck::Damaged(reason) => {
                let event = FaultEvent {
                    kind: FaultKind::CheckpointDamaged,
                    attempt: None,
                    detail: format!("{reason}; capturing the position again"),
                };
                tracing::warn!(position = i, "{event}");
                faults.push(event);
            }
        }
        if options
            .stop_after
            .is_some_and(|limit| new_positions >= limit)
        {
            return Ok(Outcome::Stopped { new_positions });
        }
        let t0 = Instant::now();
        let sim_t0 = rig.clock.now();
        if let Some(sim) = sim {
            sim.begin_position(i as u64);
        }
        let exposures = match (spec.bracketing, &previous) {
            (Bracketing::Adaptive, Some(prev)) => {
                let opts = hdr::BracketOptions {
                    black_level_dn: black,
                    ..Default::default()
                };
                // Plan for the pixels that give samples at this lamp angle.
                let roi = position::lit_mask(
                    &view,
                    &calibration,
                    angle,
                    ForwardOptions::default().max_incidence_deg,
                );
                hdr::plan_exposures(Some(prev), Some(&roi), &opts)?.exposures_s
            }
            _ => hdr::thesis_ladder(),
        };
        let mut log = PositionLog {
            index: i,
            angle_deg: angle,
            ..Default::default()
        };
        faults.append(&mut setup_faults);
        let (image, frames) = {
            let mut dev = Devices {
                rig: &mut *rig,
                log: &mut faults,
            };
            position::capture_series(
                &mut dev,
                &ctx,
                angle,
                &exposures,
                &mut log.series_attempts,
                &mut log.timings,
            )?
        };
        let t = Instant::now();
        let info = position::write_hdr(dir.root(), i, angle, &image, &frames)?;
        if let (true, Some(sim)) = (options.save_truth, sim) {
            let t = sim.position_truth(angle);
            hdr::write_truth_exr(
                &hdr::truth_path(dir.root(), i),
                image.width,
                image.height,
                &t.signal_rate_dn_per_s,
                &info,
            )?;
        }
        if spec.keep_frames {
            layout::write_atomic(&dir.frames(i), &gantry_hal::encode_frames(&frames))?;
        }
        log.timings.hdr_write_s = t.elapsed().as_secs_f64();
        let t = Instant::now();
        let samples = position::samples_of(&ctx, &image, i, angle)?;
        log.timings.samples_s = t.elapsed().as_secs_f64();
        let t = Instant::now();
        samples.write(&dir.samples(i))?;
        log.exposures_s = exposures;
        log.samples = samples.samples.len();
        log.valid_pixels = image.valid_count();
        log.faults = faults;
        log.sim_time_s = (rig.clock.now() - sim_t0).as_secs_f64();
        log.timings.checkpoint_s = t.elapsed().as_secs_f64();
        log.wall_s = t0.elapsed().as_secs_f64();
        layout::write_json(&dir.log(i), &log)?;
        dir.seal_position(i)?;
        previous = Some(image);
        new_positions += 1;
        options.report(Stage::Positions, i + 1, n);
    }
    let stages = Stages {
        setup: setup_s,
        capture: t_capture.elapsed().as_secs_f64(),
        ..Default::default()
    };
    let done = finish_job(&dir, spec, &ctx, pattern, options, stages, start)?;
    Ok(Outcome::Finished(Box::new(done)))
}

/// When a job started, and the process's resident memory then (not the job's to budget).
#[derive(Clone, Copy)]
struct JobStart {
    time: Instant,
    resident: usize,
}

impl JobStart {
    fn now() -> Self {
        Self {
            time: Instant::now(),
            resident: brdf::process::resident_bytes().unwrap_or(0) as usize,
        }
    }
}

/// Binning, validation, report and (when asked) the inverse mapping.
fn finish_job(
    dir: &JobDir,
    spec: &JobSpec,
    ctx: &PositionContext<'_>,
    pattern: gantry_hal::BayerPattern,
    options: &RunOptions,
    mut stages: Stages,
    start: JobStart,
) -> Result<Finished> {
    let truth = finish::truth_of(spec)?;
    let n = spec.angles_deg.len();
    options.report(Stage::Binning, 0, 1);
    let t_bin = Instant::now();
    let binned = finish::bin_positions(dir, spec, options.memory_mb, start.resident)?;
    stages.binning = t_bin.elapsed().as_secs_f64();
    options.report(Stage::Binning, 1, 1);
    options.report(Stage::Validation, 0, n);
    let t_val = Instant::now();
    let validation = finish::validate_positions(dir, spec, ctx, &binned.table, pattern)?;
    stages.validation = t_val.elapsed().as_secs_f64();
    options.report(Stage::Validation, n, n);
    let report = finish::write_report(
        dir,
        spec,
        ctx,
        &binned,
        validation,
        truth.as_ref(),
        stages,
        start.time,
    )?;
    let inverse = if options.inverse {
        options.report(Stage::Inverse, 0, 1);
        let r = finish::inverse_mapping(dir, spec, ctx, truth.as_ref())?;
        options.report(Stage::Inverse, 1, 1);
        Some(r)
    } else {
        None
    };
    Ok(Finished { report, inverse })
}

/// Re-runs HDR (from the frames a capture kept) and binning, validation and report of the
/// capture in `dir`, without the devices. `options` supplies the memory budget, the inverse
/// mapping and progress; the rest of it is ignored.
pub fn rebin(dir: impl AsRef<Path>, options: &RunOptions) -> Result<Finished> {
    let start = JobStart::now();
    let dir = JobDir::new(dir.as_ref());
    let _lock = layout::JobLock::acquire(&dir)?;
    let spec: JobSpec = layout::read_json(&dir.job())?;
    spec.validate()?;
    let calibration = calib::Calibration::read(&dir.calibration())?;
    let lamp_constant = layout::read_lamp_constant(&dir.lamp_constant())?;
    let defects = layout::HotPixels::read_map(&dir.defects())?;
    let pattern = match spec.backend {
        Backend::Sim => {
            hal_sim::SimRig::from_config(spec.sim_config())?
                .rig()
                .camera
                .info()
                .pattern
        }
        Backend::Rig => gantry_hal::BayerPattern::Rggb,
    };
    let view = SphereView::new(&calibration, move |x, y| pattern.channel_at(x, y), 85.0);
    let ctx = PositionContext {
        view: &view,
        calibration: &calibration,
        defects: &defects,
        lamp_constant,
        assignment: spec.bin_assignment,
        ambient: if dir.ambient().exists() {
            Some(layout::read_json::<[f64; 3]>(&dir.ambient())?)
        } else {
            None
        },
    };
    let t_hdr = Instant::now();
    let mut remerged = 0;
    let n = spec.angles_deg.len();
    for (i, &angle) in spec.angles_deg.iter().enumerate() {
        let fp = dir.frames(i);
        if fp.exists() {
            let bytes = std::fs::read(&fp).map_err(error::io(&fp))?;
            let frames =
                gantry_hal::decode_frames(&bytes).map_err(|e| AcquireError::Malformed {
                    path: fp.clone(),
                    reason: e.to_string(),
                })?;
            let image = hdr::merge(&frames, Some(&defects), &hdr::MergeOptions::default())?;
            position::write_hdr(dir.root(), i, angle, &image, &frames)?;
            position::samples_of(&ctx, &image, i, angle)?.write(&dir.samples(i))?;
            dir.seal_position(i)?;
            remerged += 1;
        }
        options.report(Stage::Positions, i + 1, n);
    }
    tracing::info!(remerged, "positions re-merged from stored frames");
    let stages = Stages {
        capture: t_hdr.elapsed().as_secs_f64(),
        ..Default::default()
    };
    finish_job(&dir, &spec, &ctx, pattern, options, stages, start)
}
