//! The job as an ordered list of checkpointed stages.

use crate::devices::{self, Devices, FaultEvent, FaultKind};
use crate::error::{AcquireError, Result};
use crate::finish;
use crate::layout::{self, JobDir, PositionCheck};
use crate::position::{self, PositionContext, PositionLog};
use crate::report::{InverseReport, Report, Stages};
use crate::setup::{self, CalibrationSource, Station};
use crate::spec::{Bracketing, JobRecord, JobSpec};
use crate::{Finished, Outcome, RunOptions, Stage};
use binning::{BinnedTable, ForwardOptions, SphereView};
use gantry_hal::BayerPattern;
use hdr::{DefectMap, HdrImage};
use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::time::Instant;

/// A stage of the job, in the order it runs; each has its checkpoint in the job directory.
///
/// The job as an ordered list of checkpointed stages ([`JobStage::ALL`]). Every stage goes
/// through [`load_or_compute`]: its checkpoint is loaded when it is there and valid, otherwise
/// the stage is computed and its checkpoint written atomically. A stage computed anew makes the
/// checkpoints of the results after it (binning, report, inverse mapping) stale.
///
/// # Examples
///
/// ```
/// use acquire::{JobDir, JobStage};
/// use std::path::Path;
///
/// assert_eq!(JobStage::ALL[0], JobStage::Geometry);
/// // a re-bin runs the last three stages again, from the stored positions
/// assert_eq!(JobStage::RESULTS, JobStage::ALL[5..]);
/// let dir = JobDir::new("capture");
/// assert_eq!(JobStage::DarkFrame.checkpoint(&dir), Path::new("capture/defects.json"));
/// ```
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum JobStage {
    /// The geometry (`calibration.json`); then the rig is homed.
    Geometry,
    /// The dark frame's hot photosites (`defects.json`).
    DarkFrame,
    /// The ambient signal with the lamp off (`ambient.json`).
    Ambient,
    /// The absolute scale (`lamp_constant.json`); a white-standard run ends here.
    LampConstant,
    /// The lamp positions (each position is its own checkpoint, `positions/NNN.*`).
    Positions,
    /// Robust binning (`brdf.binary`, `counts.bin`, then `binning.json`).
    Binning,
    /// Validation by re-rendering and the report (`report.json`).
    Report,
    /// The inverse mapping, when asked for (`inverse_report.json`).
    Inverse,
}

impl JobStage {
    /// Every stage, in order.
    pub const ALL: [JobStage; 8] = [
        JobStage::Geometry,
        JobStage::DarkFrame,
        JobStage::Ambient,
        JobStage::LampConstant,
        JobStage::Positions,
        JobStage::Binning,
        JobStage::Report,
        JobStage::Inverse,
    ];

    /// The stages after the capture, which a re-bin runs again.
    pub const RESULTS: [JobStage; 3] = [JobStage::Binning, JobStage::Report, JobStage::Inverse];

    /// The file whose presence marks the stage done (for the positions, their folder).
    pub fn checkpoint(self, dir: &JobDir) -> PathBuf {
        match self {
            JobStage::Geometry => dir.calibration(),
            JobStage::DarkFrame => dir.defects(),
            JobStage::Ambient => dir.ambient(),
            JobStage::LampConstant => dir.lamp_constant(),
            JobStage::Positions => dir.root().join("positions"),
            JobStage::Binning => dir.binning(),
            JobStage::Report => dir.report(),
            JobStage::Inverse => dir.inverse_report(),
        }
    }
}

/// The one step of every stage: loads the checkpoint at `path` with `load` when `reuse` allows
/// it and it is there and valid (an unusable checkpoint is logged and computed again),
/// otherwise computes the value and writes it with `store` (atomically). Returns the value
/// and whether it was computed.
///
/// # Examples
///
/// The second call finds the checkpoint and does not compute again:
///
/// ```
/// use acquire::load_or_compute;
///
/// let dir = tempfile::tempdir()?;
/// let path = dir.path().join("answer.txt");
/// let load = |p: &std::path::Path| Ok(std::fs::read_to_string(p).unwrap().parse::<u32>().unwrap());
/// let store = |p: &std::path::Path, v: &u32| Ok(std::fs::write(p, v.to_string()).unwrap());
/// let (value, computed) = load_or_compute(&path, true, load, || Ok(42), store)?;
/// assert_eq!((value, computed), (42, true));
/// let (value, computed) = load_or_compute(&path, true, load, || unreachable!(), store)?;
/// assert_eq!((value, computed), (42, false));
/// # Ok::<(), Box<dyn std::error::Error>>(())
/// ```
pub fn load_or_compute<T>(
    path: &Path,
    reuse: bool,
    load: impl FnOnce(&Path) -> Result<T>,
    compute: impl FnOnce() -> Result<T>,
    store: impl FnOnce(&Path, &T) -> Result<()>,
) -> Result<(T, bool)> {
    if reuse && path.exists() {
        match load(path) {
            Ok(value) => return Ok((value, false)),
            Err(e) => tracing::warn!("checkpoint unusable, computing it again: {e}"),
        }
    }
    let value = compute()?;
    store(path, &value)?;
    Ok((value, true))
}

/// [`load_or_compute`] of a JSON checkpoint.
fn json_checkpoint<T: serde::Serialize + serde::de::DeserializeOwned>(
    path: &Path,
    reuse: bool,
    compute: impl FnOnce() -> Result<T>,
) -> Result<(T, bool)> {
    load_or_compute(path, reuse, layout::read_json, compute, |p, v| {
        layout::write_json(p, v)
    })
}

/// When a job started, and the process's resident memory then (not the job's to budget).
#[derive(Clone, Copy)]
pub(crate) struct JobStart {
    pub(crate) time: Instant,
    pub(crate) resident: usize,
}

impl JobStart {
    pub(crate) fn now() -> Self {
        Self {
            time: Instant::now(),
            resident: brdf::resident_bytes().unwrap_or(0) as usize,
        }
    }
}

/// What the stages have measured so far.
pub(crate) struct Job<'a> {
    dir: JobDir,
    record: JobRecord,
    spec: JobSpec,
    options: &'a RunOptions,
    start: JobStart,
    /// The devices (none for a re-bin).
    station: Option<&'a mut Station>,
    /// Whether a stage was computed anew that the results' checkpoints do not reflect.
    stale: bool,
    stages: Stages,
    pattern: BayerPattern,
    calibration: Option<calib::Calibration>,
    view: Option<SphereView>,
    defects: Option<DefectMap>,
    ambient: Option<[f64; 3]>,
    lamp_constant: Option<[f64; 3]>,
    /// Faults met before the first position (homing), for its log.
    setup_faults: Vec<FaultEvent>,
    binned: Option<BinnedTable>,
    report: Option<Report>,
    inverse: Option<InverseReport>,
}

fn missing(what: &str) -> AcquireError {
    AcquireError::InvalidJob(format!("{what} is not known at this stage"))
}

/// The geometry, sphere view and defect map the earlier stages measured.
fn setup_of<'s>(
    calibration: &'s Option<calib::Calibration>,
    view: &'s Option<SphereView>,
    defects: &'s Option<DefectMap>,
) -> Result<(&'s calib::Calibration, &'s SphereView, &'s DefectMap)> {
    Ok((
        calibration
            .as_ref()
            .ok_or_else(|| missing("the geometry"))?,
        view.as_ref().ok_or_else(|| missing("the sphere view"))?,
        defects.as_ref().ok_or_else(|| missing("the defect map"))?,
    ))
}

impl<'a> Job<'a> {
    pub(crate) fn new(
        dir: JobDir,
        record: JobRecord,
        options: &'a RunOptions,
        start: JobStart,
        station: Option<&'a mut Station>,
    ) -> Self {
        Self {
            dir,
            spec: record.spec(),
            record,
            options,
            start,
            station,
            stale: false,
            stages: Stages::default(),
            pattern: BayerPattern::Rggb,
            calibration: None,
            view: None,
            defects: None,
            ambient: None,
            lamp_constant: None,
            setup_faults: Vec::new(),
            binned: None,
            report: None,
            inverse: None,
        }
    }

    /// A job whose capture is on disk, for a re-bin: its geometry, lamp constant, defects and
    /// (when measured) ambient signal, with the camera's Bayer `pattern`; the results are
    /// stale.
    pub(crate) fn captured(mut self, pattern: BayerPattern) -> Result<Self> {
        let dir = &self.dir;
        let calibration = calib::Calibration::read(&dir.calibration())?;
        self.lamp_constant = Some(layout::read_lamp_constant(&dir.lamp_constant())?);
        self.defects = Some(layout::HotPixels::read_map(&dir.defects())?);
        self.ambient = if dir.ambient().exists() {
            Some(layout::read_json::<[f64; 3]>(&dir.ambient())?)
        } else {
            None
        };
        self.pattern = pattern;
        self.view = Some(SphereView::new(
            &calibration,
            move |x, y| pattern.channel_at(x, y),
            85.0,
        ));
        self.calibration = Some(calibration);
        self.stale = true;
        Ok(self)
    }

    /// The context of a position's samples.
    fn ctx(&self) -> Result<PositionContext<'_>> {
        let (calibration, view, defects) = setup_of(&self.calibration, &self.view, &self.defects)?;
        Ok(PositionContext {
            view,
            calibration,
            defects,
            lamp_constant: self
                .lamp_constant
                .ok_or_else(|| missing("the lamp constant"))?,
            assignment: self.spec.bin_assignment,
            ambient: self.ambient,
        })
    }

    fn station(&mut self) -> Result<&mut Station> {
        self.station
            .as_deref_mut()
            .ok_or_else(|| missing("the station"))
    }

    /// Runs `stage`; `Some` when the job ends there.
    pub(crate) fn stage(&mut self, stage: JobStage) -> Result<Option<Outcome>> {
        let path = stage.checkpoint(&self.dir);
        match stage {
            JobStage::Geometry => self.geometry(&path)?,
            JobStage::DarkFrame => {
                let rig = &mut self.station()?.rig;
                let (map, _) = load_or_compute(
                    &path,
                    true,
                    layout::HotPixels::read_map,
                    || setup::dark_frame_defects(rig),
                    |p, map| layout::write_json(p, &layout::HotPixels::of(map)),
                )?;
                self.defects = Some(map);
            }
            JobStage::Ambient => {
                let (_, view, defects) = setup_of(&self.calibration, &self.view, &self.defects)?;
                let station = self
                    .station
                    .as_deref_mut()
                    .ok_or_else(|| missing("the station"))?;
                let (ambient, _) = json_checkpoint(&path, true, || {
                    setup::lamp_off_ambient(&mut station.rig, view, defects)
                })?;
                tracing::info!(?ambient, "ambient rate with the lamp off, DN/s");
                self.ambient = Some(ambient);
            }
            JobStage::LampConstant => return self.lamp_constant(&path),
            JobStage::Positions => return self.positions(),
            JobStage::Binning => {
                self.options.report(Stage::Binning, 0, 1);
                let t = Instant::now();
                let (dir, record, options) = (&self.dir, &self.record, self.options);
                let (binned, computed) = load_or_compute(
                    &path,
                    !self.stale,
                    |_| finish::load_binned(dir),
                    || finish::bin_positions(dir, record, options.memory_mb, self.start.resident),
                    |_, binned| finish::store_binned(dir, binned),
                )?;
                self.stale |= computed;
                self.stages.binning = t.elapsed().as_secs_f64();
                self.binned = Some(binned);
                self.options.report(Stage::Binning, 1, 1);
            }
            JobStage::Report => {
                let ctx = self.ctx()?;
                let binned = self.binned.as_ref().ok_or_else(|| missing("the table"))?;
                let (dir, record, options, pattern) =
                    (&self.dir, &self.record, self.options, self.pattern);
                let mut stages = self.stages.clone();
                let truth = || self.truth();
                let (report, computed) = json_checkpoint(&path, !self.stale, || {
                    let n = record.angles_deg.len();
                    options.report(Stage::Validation, 0, n);
                    let t = Instant::now();
                    let validation =
                        finish::validate_positions(dir, record, &ctx, &binned.table, pattern)?;
                    stages.validation = t.elapsed().as_secs_f64();
                    options.report(Stage::Validation, n, n);
                    let truth = truth()?;
                    finish::report_of(
                        dir,
                        record,
                        &ctx,
                        binned,
                        validation,
                        truth.as_ref(),
                        stages,
                        self.start.time,
                    )
                })?;
                self.stale |= computed;
                self.report = Some(report);
            }
            JobStage::Inverse if self.options.inverse => {
                self.options.report(Stage::Inverse, 0, 1);
                let ctx = self.ctx()?;
                let (dir, record) = (&self.dir, &self.record);
                let (inverse, _) = json_checkpoint(&path, !self.stale, || {
                    finish::inverse_mapping(dir, record, &ctx, self.truth()?.as_ref())
                })?;
                self.inverse = Some(inverse);
                self.options.report(Stage::Inverse, 1, 1);
            }
            JobStage::Inverse => {}
        }
        Ok(None)
    }

    /// The truth the report compares with: the simulator's on a station, the recorded
    /// material's for a re-bin of a simulated job.
    fn truth(&self) -> Result<Option<finish::Truth>> {
        match &self.station {
            Some(station) => station.simulator.as_ref().map(|s| s.truth()).transpose(),
            None => finish::truth_of(&self.record),
        }
    }

    /// The geometry (a given file wins over the stored one, which wins over calibrating), the
    /// sphere view, and the rig homed.
    fn geometry(&mut self, path: &Path) -> Result<()> {
        let source = self.options.calibration.clone();
        let station = self
            .station
            .as_deref_mut()
            .ok_or_else(|| missing("the station"))?;
        let read = |p: &Path| Ok(calib::Calibration::read(p)?);
        let (calibration, _) = load_or_compute(
            path,
            !matches!(source, CalibrationSource::File(_)),
            read,
            || match (&source, &station.simulator) {
                (CalibrationSource::File(file), _) => read(file),
                (CalibrationSource::TrueGeometry, Some(sim)) => sim.true_calibration(),
                (_, Some(sim)) => sim.calibrate(),
                (_, None) => Err(AcquireError::InvalidJob(
                    "on devices a calibration file is needed (calibrate the rig first)".into(),
                )),
            },
            |p, c| Ok(c.write(p)?),
        )?;
        tracing::info!(?source, "geometry");
        let info = station.rig.camera.info();
        if (info.width, info.height) != (calibration.camera.width, calibration.camera.height) {
            return Err(AcquireError::InvalidJob(format!(
                "the camera delivers {}x{} frames but the calibration is for {}x{}",
                info.width, info.height, calibration.camera.width, calibration.camera.height
            )));
        }
        let pattern = info.pattern;
        let view = SphereView::new(&calibration, move |x, y| pattern.channel_at(x, y), 85.0);
        tracing::info!(pixels = view.pixels.len(), "sphere pixels");
        Devices {
            rig: &mut station.rig,
            log: &mut self.setup_faults,
        }
        .home()?;
        self.pattern = pattern;
        self.view = Some(view);
        self.calibration = Some(calibration);
        Ok(())
    }

    /// The lamp lit, then the lamp constant: a white-standard run measures it and ends the
    /// job; otherwise a given file wins over the stored one, which wins over the simulator's
    /// white standard.
    fn lamp_constant(&mut self, path: &Path) -> Result<Option<Outcome>> {
        let (calibration, view, defects) = setup_of(&self.calibration, &self.view, &self.defects)?;
        let options = self.options;
        let station = self
            .station
            .as_deref_mut()
            .ok_or_else(|| missing("the station"))?;
        station.rig.lamp.set_on(true)?;
        station.rig.lamp.wait_stable(devices::LAMP_TIMEOUT)?;
        if let Some(albedo) = options.white_reference {
            // The operator has mounted a diffuse white standard: measure the lamp constant only.
            let sim = station.simulator.as_deref();
            let k =
                setup::white_reference(&mut station.rig, calibration, view, defects, albedo, sim)?;
            layout::write_json(path, &k)?;
            return Ok(Some(Outcome::LampConstant(k)));
        }
        let (k, _) = load_or_compute(
            path,
            options.lamp_constant.is_none(),
            layout::read_lamp_constant,
            || match (&options.lamp_constant, &station.simulator) {
                (Some(file), _) => layout::read_lamp_constant(file),
                (None, Some(sim)) => sim.lamp_constant(calibration, view, defects),
                (None, None) => Err(AcquireError::InvalidJob(
                    "on devices a lamp constant file is needed (from a white-standard run)".into(),
                )),
            },
            layout::write_json,
        )?;
        self.lamp_constant = Some(k);
        Ok(None)
    }

    /// The lamp positions not yet captured; `Some` when the job stops as asked.
    fn positions(&mut self) -> Result<Option<Outcome>> {
        let station = self.station.take().ok_or_else(|| missing("the station"))?;
        let setup_faults = std::mem::take(&mut self.setup_faults);
        self.stages.setup = self.start.time.elapsed().as_secs_f64();
        let t = Instant::now();
        let captured = self.capture_positions(&mut *station, setup_faults);
        self.station = Some(station);
        let (outcome, new_positions) = captured?;
        // New positions make the results stored before them stale.
        self.stale |= new_positions > 0;
        self.stages.capture = t.elapsed().as_secs_f64();
        Ok(outcome)
    }

    /// Captures the positions whose checkpoints are not done; returns how the stage ended and
    /// how many positions it captured. The faults met before (homing) go to the first one.
    fn capture_positions(
        &self,
        station: &mut Station,
        setup_faults: Vec<FaultEvent>,
    ) -> Result<(Option<Outcome>, usize)> {
        // The black level matters only to adaptive bracketing.
        let black = match self.spec.bracketing {
            Bracketing::Adaptive => setup::black_level(&mut station.rig)?,
            Bracketing::Full => 0.0,
        };
        let ctx = self.ctx()?;
        let dir = &self.dir;
        // Each position's files (HDR image, kept frames, samples, log, seal) are written by a
        // writer thread while the next position is captured; the hand-over waits while the
        // writer is busy, so at most one position is in flight. A position is sealed only
        // after all its files are written, so a job stopped or failed at any point resumes
        // from its last sealed position.
        std::thread::scope(|scope| {
            let (to_writer, from_capture) = std::sync::mpsc::sync_channel::<CapturedPosition>(0);
            let ctx = &ctx;
            let (options, n) = (self.options, self.spec.angles_deg.len());
            let writer = scope.spawn(move || -> Result<()> {
                for captured in from_capture {
                    let i = captured.log.index;
                    write_position(ctx, dir, captured)?;
                    // a position counts as done once it is sealed, not when handed over
                    options.report(Stage::Positions, i + 1, n);
                }
                Ok(())
            });
            let captured = self.capture_loop(station, setup_faults, ctx, black, &to_writer);
            drop(to_writer);
            let written = writer.join().unwrap_or(Err(AcquireError::WriterStopped));
            // The writer's error is about an earlier position than the capture loop's.
            written?;
            captured
        })
    }

    /// The capture side of [`Self::capture_positions`]: captures each position not yet done
    /// and hands it to the writer thread.
    fn capture_loop(
        &self,
        station: &mut Station,
        mut setup_faults: Vec<FaultEvent>,
        ctx: &PositionContext<'_>,
        black: f64,
        to_writer: &std::sync::mpsc::SyncSender<CapturedPosition>,
    ) -> Result<(Option<Outcome>, usize)> {
        let (dir, spec, options) = (&self.dir, &self.spec, self.options);
        let n = spec.angles_deg.len();
        let mut previous: Option<Arc<HdrImage>> = None;
        let mut new_positions = 0usize;
        for (i, &angle) in spec.angles_deg.iter().enumerate() {
            let mut faults = Vec::new();
            match dir.check_position(i) {
                PositionCheck::Done => {
                    previous = None;
                    options.report(Stage::Positions, i + 1, n);
                    continue;
                }
                PositionCheck::Missing => {}
                PositionCheck::Damaged(reason) => {
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
                return Ok((Some(Outcome::Stopped { new_positions }), new_positions));
            }
            faults.append(&mut setup_faults);
            let captured = capture_position(
                station,
                ctx,
                spec,
                options,
                (i, angle),
                previous.as_deref(),
                black,
                faults,
            )?;
            previous = Some(captured.image.clone());
            let t = Instant::now();
            if to_writer.send(captured).is_err() {
                // The writer stopped on an error, which the caller reports before this one.
                return Err(AcquireError::WriterStopped);
            }
            tracing::trace!(
                position = i,
                wait_s = t.elapsed().as_secs_f64(),
                "handed to the writer"
            );
            new_positions += 1;
        }
        Ok((None, new_positions))
    }

    /// Re-merges the HDR images of the positions whose frames were kept (a re-bin).
    pub(crate) fn remerge(&mut self) -> Result<()> {
        let t = Instant::now();
        let ctx = self.ctx()?;
        let (dir, spec) = (&self.dir, &self.spec);
        let mut remerged = 0;
        let n = spec.angles_deg.len();
        for (i, &angle) in spec.angles_deg.iter().enumerate() {
            let fp = dir.frames(i);
            if fp.exists() {
                let bytes = std::fs::read(&fp).map_err(crate::error::io(&fp))?;
                let frames =
                    gantry_hal::decode_frames(&bytes).map_err(|e| AcquireError::Malformed {
                        path: fp.clone(),
                        reason: e.to_string(),
                    })?;
                let image = hdr::merge(&frames, Some(ctx.defects), &hdr::MergeOptions::default())?;
                let info = position::position_info(i, angle, &frames);
                position::write_hdr(dir.root(), i, &image, &info)?;
                position::samples_of(&ctx, &image, i, angle)?.write(&dir.samples(i))?;
                dir.seal_position(i)?;
                remerged += 1;
            }
            self.options.report(Stage::Positions, i + 1, n);
        }
        tracing::info!(remerged, "positions re-merged from stored frames");
        self.stages.capture = t.elapsed().as_secs_f64();
        Ok(())
    }

    /// The finished job.
    pub(crate) fn finished(self) -> Result<Finished> {
        Ok(Finished {
            report: self.report.ok_or_else(|| missing("the report"))?,
            inverse: self.inverse,
        })
    }
}

/// A captured position on its way to the writer thread.
struct CapturedPosition {
    image: Arc<HdrImage>,
    /// The exposure frames, when the job keeps them.
    frames: Option<Vec<gantry_hal::BayerFrame>>,
    /// The HDR image's metadata.
    info: hdr::PositionInfo,
    /// The simulator's true signal rate, when asked for.
    truth: Option<Vec<f32>>,
    /// The position's log, complete but for its samples and the writer's timings.
    log: PositionLog,
    /// When the position began.
    started: Instant,
}

/// Captures position `i` at lamp angle `angle` and merges its HDR image (which plans the next
/// position's exposures under adaptive bracketing); [`write_position`] writes it.
#[allow(clippy::too_many_arguments)]
fn capture_position(
    station: &mut Station,
    ctx: &PositionContext<'_>,
    spec: &JobSpec,
    options: &RunOptions,
    (i, angle): (usize, f64),
    previous: Option<&HdrImage>,
    black: f64,
    mut faults: Vec<FaultEvent>,
) -> Result<CapturedPosition> {
    let started = Instant::now();
    let sim_t0 = station.rig.clock.now();
    if let Some(sim) = &station.simulator {
        sim.begin_position(i as u64);
    }
    let exposures = match (spec.bracketing, previous) {
        (Bracketing::Adaptive, Some(prev)) => {
            let opts = hdr::BracketOptions {
                black_level_dn: black,
                ladder: spec.ladder(),
                ..Default::default()
            };
            // Plan for the pixels that give samples at this lamp angle.
            let roi = position::lit_mask(
                ctx.view,
                ctx.calibration,
                angle,
                ForwardOptions::default().max_incidence_deg,
            );
            hdr::plan_exposures(Some(prev), Some(&roi), &opts)?.exposures_s
        }
        _ => spec.ladder(),
    };
    let mut log = PositionLog {
        index: i,
        angle_deg: angle,
        ..Default::default()
    };
    let (image, frames) = {
        let mut dev = Devices {
            rig: &mut station.rig,
            log: &mut faults,
        };
        position::capture_series(
            &mut dev,
            ctx,
            angle,
            &exposures,
            &mut log.series_attempts,
            &mut log.timings,
        )?
    };
    let info = position::position_info(i, angle, &frames);
    let truth = match (options.save_truth, &station.simulator) {
        (true, Some(sim)) => Some(sim.signal_rate(angle)),
        _ => None,
    };
    log.exposures_s = exposures;
    log.valid_pixels = image.valid_count();
    log.faults = faults;
    log.sim_time_s = (station.rig.clock.now() - sim_t0).as_secs_f64();
    Ok(CapturedPosition {
        image: Arc::new(image),
        frames: spec.keep_frames.then_some(frames),
        info,
        truth,
        log,
        started,
    })
}

/// Writes a captured position's files, in order: HDR image (with the truth image and the kept
/// frames when asked), BRDF samples, log, and last the seal that marks the position done.
fn write_position(
    ctx: &PositionContext<'_>,
    dir: &JobDir,
    captured: CapturedPosition,
) -> Result<()> {
    let CapturedPosition {
        image,
        frames,
        info,
        truth,
        mut log,
        started,
    } = captured;
    let (i, angle) = (log.index, log.angle_deg);
    let t = Instant::now();
    position::write_hdr(dir.root(), i, &image, &info)?;
    if let Some(truth) = &truth {
        hdr::write_truth_exr(
            &hdr::truth_path(dir.root(), i),
            image.width,
            image.height,
            truth,
            &info,
        )?;
    }
    if let Some(frames) = &frames {
        layout::write_atomic(&dir.frames(i), &gantry_hal::encode_frames(frames))?;
    }
    log.timings.hdr_write_s = t.elapsed().as_secs_f64();
    let t = Instant::now();
    let samples = position::samples_of(ctx, &image, i, angle)?;
    log.timings.samples_s = t.elapsed().as_secs_f64();
    let t = Instant::now();
    samples.write(&dir.samples(i))?;
    log.samples = samples.samples.len();
    log.timings.background = true;
    log.timings.checkpoint_s = t.elapsed().as_secs_f64();
    log.wall_s = started.elapsed().as_secs_f64();
    layout::write_json(&dir.log(i), &log)?;
    dir.seal_position(i)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_checkpoint_is_loaded_when_valid_and_computed_again_when_not() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("ambient.json");
        let compute = |v: [f64; 3]| move || Ok(v);
        // Absent: computed and written.
        let (v, computed) = json_checkpoint(&path, true, compute([1.0, 2.0, 3.0])).unwrap();
        assert_eq!((v, computed), ([1.0, 2.0, 3.0], true));
        // Present and valid: loaded, the computation not run.
        let (v, computed) = json_checkpoint(&path, true, || -> Result<[f64; 3]> {
            panic!("a valid checkpoint was computed again")
        })
        .unwrap();
        assert_eq!((v, computed), ([1.0, 2.0, 3.0], false));
        // Stale: computed again although valid.
        let (v, computed) = json_checkpoint(&path, false, compute([4.0, 5.0, 6.0])).unwrap();
        assert_eq!((v, computed), ([4.0, 5.0, 6.0], true));
        // Unusable: computed again and rewritten.
        std::fs::write(&path, b"[1.0, 2").unwrap();
        let (v, computed) = json_checkpoint(&path, true, compute([7.0, 8.0, 9.0])).unwrap();
        assert_eq!((v, computed), ([7.0, 8.0, 9.0], true));
        assert_eq!(
            layout::read_json::<[f64; 3]>(&path).unwrap(),
            [7.0, 8.0, 9.0]
        );
    }

    #[test]
    fn every_stage_has_its_own_checkpoint_and_the_results_come_last() {
        let dir = JobDir::new("/job");
        let files: std::collections::HashSet<PathBuf> =
            JobStage::ALL.iter().map(|s| s.checkpoint(&dir)).collect();
        assert_eq!(files.len(), JobStage::ALL.len());
        assert_eq!(JobStage::ALL[JobStage::ALL.len() - 3..], JobStage::RESULTS);
    }
}
