//! `gantry capture` and `gantry rebin`: the lab operator's main job, run by [`acquire`].
//!
//! This module turns the command line into an [`acquire::JobSpec`], the station (an
//! [`acquire::SimSetup`] on the simulator) and [`acquire::RunOptions`], calls [`acquire::run`],
//! shows progress and prints the outcome; the job itself (its directory layout, checkpoints,
//! retry policy and report) is documented in the `acquire` crate.

use acquire::{
    Bracketing, CalibrationSource, Finished, JobSpec, Outcome, Progress, RunOptions, SimSetup,
    Stage, Station,
};
use anyhow::{bail, Context, Result};
use binning::BinAssignment;
use clap::{Args, ValueEnum};
use std::path::PathBuf;
use std::sync::{Arc, Mutex};

/// Command-line form of [`Bracketing`].
#[derive(ValueEnum, Clone, Copy, Debug, PartialEq, Eq)]
pub enum BracketingArg {
    /// The thesis's 18 exposures, 40 µs to 20 s, at every position.
    Full,
    /// Exposures chosen from the previous position's radiance range.
    Adaptive,
}

impl From<BracketingArg> for Bracketing {
    fn from(a: BracketingArg) -> Self {
        match a {
            BracketingArg::Full => Bracketing::Full,
            BracketingArg::Adaptive => Bracketing::Adaptive,
        }
    }
}

/// Command-line form of [`BinAssignment`].
#[derive(ValueEnum, Clone, Copy, Debug, PartialEq, Eq)]
pub enum BinAssignmentArg {
    /// Nearest grid node.
    NearestNode,
    /// The MERL reference reader's truncation (the node's cell lies above it).
    ReferenceReader,
}

impl From<BinAssignmentArg> for BinAssignment {
    fn from(a: BinAssignmentArg) -> Self {
        match a {
            BinAssignmentArg::NearestNode => BinAssignment::NearestNode,
            BinAssignmentArg::ReferenceReader => BinAssignment::ReferenceReader,
        }
    }
}

/// Command-line form of [`fast_capture::Weighting`].
#[derive(ValueEnum, Clone, Copy, Debug, PartialEq, Eq)]
pub enum WeightingArg {
    /// By the entry's share of the cosine-weighted error under the model's mean material.
    Cosine,
    /// Every entry alike.
    Uniform,
}

impl From<WeightingArg> for fast_capture::Weighting {
    fn from(a: WeightingArg) -> Self {
        match a {
            WeightingArg::Cosine => fast_capture::Weighting::Cosine,
            WeightingArg::Uniform => fast_capture::Weighting::Uniform,
        }
    }
}

/// Command-line form of [`fast_capture::Residual`].
#[derive(ValueEnum, Clone, Copy, Debug, PartialEq, Eq)]
pub enum ResidualArg {
    /// Spread the misfit at the measured entries over the grid by pull-push (thesis §6.4).
    PullPush,
    /// Completed entries are the model's prediction alone.
    Dropped,
}

impl From<ResidualArg> for fast_capture::Residual {
    fn from(a: ResidualArg) -> Self {
        match a {
            ResidualArg::PullPush => fast_capture::Residual::PullPush,
            ResidualArg::Dropped => fast_capture::Residual::Dropped,
        }
    }
}

/// Arguments of `gantry capture`.
#[derive(Args, Debug, Clone)]
pub struct CaptureArgs {
    /// Run on the simulated rig.
    #[arg(long, required_unless_present = "rig", conflicts_with = "rig")]
    pub sim: bool,
    /// Run on the real devices described by this rig configuration (TOML).
    #[arg(long)]
    pub rig: Option<PathBuf>,
    /// Material of the simulated sample sphere (material spec).
    #[arg(long, default_value = "merl:blue-acrylic")]
    pub material: String,
    /// Output directory.
    #[arg(long)]
    pub out: PathBuf,
    /// Use this calibration file instead of calibrating.
    #[arg(long)]
    pub calibration: Option<PathBuf>,
    /// Simulator only: bin with the simulator's true geometry instead of calibrating first.
    #[arg(long, conflicts_with = "calibration")]
    pub true_geometry: bool,
    /// Lamp constant file (JSON, from a white-reference run); required on real devices.
    #[arg(long)]
    pub lamp_constant: Option<PathBuf>,
    /// Number of lamp positions over the half circle (the thesis: 330).
    #[arg(long, default_value_t = 330)]
    pub positions: usize,
    /// Sensor scale of the simulated camera (1 = 1300 × 1030; 0.25 for quick runs).
    #[arg(long, default_value_t = 1.0)]
    pub scale: f64,
    /// Seed of the simulator.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Inject the simulator's faults (1% turntable timeouts, 1% frame drops, lamp dropouts).
    #[arg(long)]
    pub faults: bool,
    /// Exposure strategy.
    #[arg(long, value_enum, default_value = "full")]
    pub bracketing: BracketingArg,
    /// Continue a job that was interrupted.
    #[arg(long)]
    pub resume: bool,
    /// Also write the simulator's noise-free signal rate per position (DIR/truth/NNN.exr).
    #[arg(long)]
    pub save_truth: bool,
    /// Keep the raw frames (DIR/frames/), so that `gantry rebin` can re-run the HDR merge.
    #[arg(long)]
    pub keep_frames: bool,
    /// Memory budget of the job, MiB (its peak resident memory; binning's value buffers get
    /// what the process and binning's fixed tables leave).
    #[arg(long, default_value_t = 512)]
    pub memory_mb: usize,
    /// Which bin a BRDF sample goes to: the nearest grid node (where a table value is read as the
    /// BRDF, as `tabulate` does), or the MERL reference reader's truncated indices.
    #[arg(long, value_enum, default_value = "nearest-node")]
    pub bin_assignment: BinAssignmentArg,
    /// Also fill the table by the thesis's inverse mapping (§3.5), as `rebin --inverse` does.
    #[arg(long)]
    pub inverse: bool,
    /// Measure only the lamp constant, with a diffuse white standard of this albedo mounted in
    /// place of the sample; writes DIR/lamp_constant.json for later `--lamp-constant`.
    #[arg(long)]
    pub white_reference: Option<f64>,
    /// Longest exposure, seconds (the thesis's ladder stops there; default: 20 s, or 2 s with
    /// --fast).
    #[arg(long)]
    pub max_exposure: Option<f64>,
    /// Fast capture: visit only the lamp positions the model needs most (planned within
    /// --budget), then complete the table from the model (needs --model). DIR/brdf.binary is the
    /// completed table; DIR/measured.npy marks the measured entries.
    #[arg(long, requires = "model")]
    pub fast: bool,
    /// The model (`gantry model build`, on full tables) that plans and completes a fast capture.
    #[arg(long, requires = "fast")]
    pub model: Option<PathBuf>,
    /// Fast capture: most lamp positions.
    #[arg(long, default_value_t = 40, requires = "fast")]
    pub fast_positions: usize,
    /// Fast capture: capture-clock budget, seconds.
    #[arg(long, default_value_t = 600.0, requires = "fast")]
    pub budget: f64,
    /// Fast capture: model components used to plan and complete.
    #[arg(long, default_value_t = 45, requires = "fast")]
    pub components: usize,
    /// Fast capture: how the planner weighs the entries a full capture reaches (by their share
    /// of the cosine-weighted error, which the highlight dominates, or alike).
    #[arg(long, value_enum, default_value = "cosine", requires = "fast")]
    pub weighting: WeightingArg,
    /// Fast capture: what the completion does with the model's misfit at the measured entries
    /// (spread to their neighbours by pull-push, or dropped).
    #[arg(long, value_enum, default_value = "pull-push", requires = "fast")]
    pub residual: ResidualArg,
    /// Fast capture: print the plan (positions, exposures, predicted clock) and stop.
    #[arg(long, requires = "fast")]
    pub dry_run: bool,
    /// Stop after this many new positions (for tests of interrupted jobs).
    #[arg(long, hide = true)]
    pub stop_after: Option<usize>,
}

/// Arguments of `gantry rebin`.
#[derive(Args, Debug, Clone)]
pub struct RebinArgs {
    /// Directory of a finished (or interrupted) capture.
    pub dir: PathBuf,
    /// Memory budget of the job, MiB (its peak resident memory; binning's value buffers get
    /// what the process and binning's fixed tables leave).
    #[arg(long, default_value_t = 512)]
    pub memory_mb: usize,
    /// Also fill the table by the thesis's inverse mapping (§3.5) from the stored HDR images:
    /// writes DIR/brdf_inverse.binary (the bins forward binning reached), DIR/brdf_inverse_all.binary
    /// (every bin reached) and DIR/inverse_report.json.
    #[arg(long)]
    pub inverse: bool,
}

/// A progress bar fed by the job's progress reports.
fn progress_bar() -> (indicatif::ProgressBar, acquire::ProgressFn) {
    let bar = indicatif::ProgressBar::new(0);
    bar.set_style(
        indicatif::ProgressStyle::with_template(
            "{spinner} [{elapsed_precise}] {bar:40} {pos}/{len} {msg}, ETA {eta}",
        )
        .unwrap_or_else(|_| indicatif::ProgressStyle::default_bar()),
    );
    let shown = bar.clone();
    let last = Mutex::new(None::<Stage>);
    let f: acquire::ProgressFn = Arc::new(move |p: &Progress| {
        let mut last = last.lock().unwrap_or_else(|e| e.into_inner());
        if *last != Some(p.stage) {
            *last = Some(p.stage);
            shown.set_length(p.total as u64);
            shown.reset_eta();
            shown.set_message(match p.stage {
                Stage::Positions => "positions",
                Stage::Binning => "binning",
                Stage::Validation => "validation",
                Stage::Inverse => "inverse mapping",
            });
        }
        shown.set_position(p.done as u64);
    });
    (bar, f)
}

impl CaptureArgs {
    /// What is measured.
    fn spec(&self) -> JobSpec {
        JobSpec {
            bracketing: self.bracketing.into(),
            keep_frames: self.keep_frames,
            bin_assignment: self.bin_assignment.into(),
            max_exposure_s: self.max_exposure,
            ..JobSpec::new(&self.material, self.positions)
        }
    }

    /// The planner's options of a fast capture.
    fn plan_options(&self) -> fast_capture::PlanOptions {
        fast_capture::PlanOptions {
            max_positions: self.fast_positions,
            budget_s: self.budget,
            max_exposure_s: Some(
                self.max_exposure
                    .unwrap_or(fast_capture::DEFAULT_MAX_EXPOSURE_S),
            ),
            components: self.components,
            weighting: self.weighting.into(),
            ..fast_capture::PlanOptions::default()
        }
    }

    /// How the simulator is set up (`--sim`).
    fn sim_setup(&self) -> SimSetup {
        SimSetup {
            scale: self.scale,
            seed: self.seed,
            faults: self.faults,
        }
    }

    /// How the job runs.
    fn options(&self, progress: acquire::ProgressFn) -> RunOptions {
        RunOptions {
            calibration: match (&self.calibration, self.true_geometry) {
                (Some(p), _) => CalibrationSource::File(p.clone()),
                (None, true) => CalibrationSource::TrueGeometry,
                (None, false) => CalibrationSource::Calibrate,
            },
            lamp_constant: self.lamp_constant.clone(),
            white_reference: self.white_reference,
            resume: self.resume,
            save_truth: self.save_truth,
            memory_mb: self.memory_mb,
            inverse: self.inverse,
            stop_after: self.stop_after,
            progress: Some(progress),
        }
    }

    /// The devices: the simulated rig (`--sim`) or those of the rig file. They are opened
    /// before anything is written, so that an absent device leaves no job behind.
    fn station(&self, spec: &JobSpec) -> Result<Station> {
        match &self.rig {
            None => Station::simulated(spec, &self.sim_setup())
                .with_context(|| format!("cannot build the simulated rig for '{}'", spec.material)),
            Some(rig) => {
                if self.calibration.is_none() {
                    bail!("with --rig pass --calibration FILE (from `gantry calibrate --rig`)");
                }
                if self.lamp_constant.is_none() && self.white_reference.is_none() {
                    bail!(
                        "with --rig pass --lamp-constant FILE (from `gantry capture --rig ... --white-reference ALBEDO`)"
                    );
                }
                Station::from_rig_file(rig)
                    .with_context(|| format!("cannot open the devices of {}", rig.display()))
            }
        }
    }
}

/// `gantry capture`.
pub fn capture(args: CaptureArgs) -> Result<()> {
    let spec = args.spec();
    spec.validate().context("bad capture parameters")?;
    if args.sim {
        args.sim_setup()
            .validate()
            .context("bad capture parameters")?;
    }
    let mut station = args.station(&spec)?;
    if args.fast {
        return fast(&args, &spec, &mut station);
    }
    if acquire::JobDir::new(&args.out).job().exists() && !args.resume {
        bail!(
            "{} already holds a capture: pass --resume to continue it, or choose another --out",
            args.out.display()
        );
    }
    let (bar, progress) = progress_bar();
    let outcome = acquire::run(&mut station, &spec, &args.options(progress), &args.out);
    bar.finish_and_clear();
    match outcome.with_context(|| format!("capture into {}", args.out.display()))? {
        Outcome::Finished(done) => print_finished(&args.out, &done),
        Outcome::Stopped { new_positions } => {
            println!("stopped after {new_positions} new positions (resume to continue)")
        }
        Outcome::LampConstant(k) => println!(
            "lamp constant [{:.6e}, {:.6e}, {:.6e}] written to {}",
            k[0],
            k[1],
            k[2],
            args.out.join("lamp_constant.json").display()
        ),
    }
    Ok(())
}

/// `gantry capture --fast`.
fn fast(args: &CaptureArgs, spec: &JobSpec, station: &mut Station) -> Result<()> {
    let path = args.model.as_ref().context("--fast needs --model")?;
    let model = reduce::Model::load(path)
        .with_context(|| format!("cannot read the model {}", path.display()))?;
    let (bar, progress) = progress_bar();
    let options = fast_capture::FastOptions {
        plan: args.plan_options(),
        run: args.options(progress),
        dry_run: args.dry_run,
        residual: args.residual.into(),
    };
    if !args.dry_run && fast_capture::FastDir::new(&args.out).plan().exists() && !args.resume {
        bail!(
            "{} already holds a fast capture: pass --resume to continue it, or choose another --out",
            args.out.display()
        );
    }
    let outcome = fast_capture::run(station, spec, &model, &options, &args.out);
    bar.finish_and_clear();
    match outcome.with_context(|| format!("fast capture into {}", args.out.display()))? {
        fast_capture::FastOutcome::Planned(plan) => print_plan(&plan),
        fast_capture::FastOutcome::Stopped { new_positions } => {
            println!("stopped after {new_positions} new positions (resume to continue)")
        }
        fast_capture::FastOutcome::Finished(report) => {
            let files = fast_capture::FastDir::new(&args.out);
            println!(
                "wrote {} ({} positions, capture clock {}; {} entries measured, {} completed from {} components)",
                files.table().display(),
                report.positions,
                report
                    .simulated_capture_s
                    .map(|s| format!("{:.1} min", s / 60.0))
                    .unwrap_or_else(|| "not simulated".into()),
                report.measured_entries,
                report.completed_entries,
                report.components
            );
            if let Some(t) = &report.truth {
                println!(
                    "vs truth over the {} entries a full capture reaches: median |log| {:.4}, cosine-weighted relative RMS {:.3} (model floor {:.4}, {:.3})",
                    t.entries,
                    t.fast.median_abs_log,
                    t.fast.cosine_weighted_relative_rms,
                    t.floor.median_abs_log,
                    t.floor.cosine_weighted_relative_rms
                );
            }
        }
    }
    Ok(())
}

fn print_plan(plan: &fast_capture::CapturePlan) {
    println!(
        "{} positions, predicted capture clock {:.1} min; exposures {:.5}–{:.3} s ({} per position)",
        plan.angles_deg.len(),
        plan.predicted_clock_s / 60.0,
        plan.exposures_s.first().copied().unwrap_or(0.0),
        plan.exposures_s.last().copied().unwrap_or(0.0),
        plan.exposures_s.len()
    );
    println!("order  angle°  entries  new  reached  predicted log sd  clock s");
    for (i, s) in plan.steps.iter().enumerate() {
        println!(
            "{:>5}  {:>6.1}  {:>7}  {:>5}  {:>6.1}%  {:>16.4}  {:>7.1}",
            i + 1,
            s.angle_deg,
            s.entries,
            s.new_entries,
            100.0 * s.covered_fraction,
            s.predicted_log_sd,
            s.clock_s
        );
    }
}

/// `gantry rebin`.
pub fn rebin(args: RebinArgs) -> Result<()> {
    let (bar, progress) = progress_bar();
    let options = RunOptions {
        memory_mb: args.memory_mb,
        inverse: args.inverse,
        progress: Some(progress),
        ..RunOptions::default()
    };
    let done = acquire::rebin(&args.dir, &options);
    bar.finish_and_clear();
    let done = done.with_context(|| format!("rebin of {}", args.dir.display()))?;
    print_finished(&args.dir, &done);
    Ok(())
}

fn print_finished(dir: &std::path::Path, done: &Finished) {
    let report = &done.report;
    let truth = |e: &Option<acquire::TableError>, what: &str| {
        e.as_ref()
            .map(|e| format!("{what}{:.4}, p90 {:.4}", e.median_abs_log, e.p90_abs_log))
            .unwrap_or_default()
    };
    println!(
        "wrote {} ({} samples, coverage {:.1}%, validation median |log| {:.4}{}{})",
        dir.join("brdf.binary").display(),
        report.samples_total,
        100.0 * report.coverage,
        report.validation_median_abs_log,
        truth(&report.truth_table_error, ", table vs truth: median |log| "),
        truth(
            &report.reciprocal_truth_error,
            " (vs reciprocity-symmetrised truth: "
        ) + if report.reciprocal_truth_error.is_some() {
            ")"
        } else {
            ""
        }
    );
    if let Some(inv) = &done.inverse {
        println!(
            "wrote {} (coverage {:.1}%, {:.0} s; vs forward table: median |log| {:.4}{})",
            dir.join("brdf_inverse.binary").display(),
            100.0 * inv.coverage,
            inv.wall_seconds,
            inv.versus_forward.median_abs_log,
            match (&inv.truth_table_error, &inv.reciprocal_truth_error) {
                (Some(t), Some(r)) => format!(
                    "; vs truth: median |log| {:.4}, p90 {:.4} (symmetrised truth: {:.4}, p90 {:.4})",
                    t.median_abs_log, t.p90_abs_log, r.median_abs_log, r.p90_abs_log
                ),
                _ => String::new(),
            }
        );
    }
}
