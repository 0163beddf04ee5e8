//! `gantry capture` and `gantry rebin`: the lab operator's main job.
//!
//! Calibration → dark frame → for every lamp position: move, bracketed exposures, HDR merge,
//! BRDF samples → robust binning → validation. Every finished position is a checkpoint on disk
//! (written atomically), so a killed job resumes with `--resume` and ends with the same bytes.
//!
//! Output directory layout:
//!
//! ```text
//! DIR/job.json               parameters of the job (checked on --resume)
//! DIR/calibration.json       geometry used for binning
//! DIR/lamp_constant.json     absolute scale (white reference)
//! DIR/defects.json           hot photosites from the 60 s dark frame
//! DIR/positions/NNN.samples  BRDF samples of position NNN (checkpoint)
//! DIR/positions/NNN.json     log of position NNN: angle, exposures, faults, timings
//! DIR/frames/NNN.frames      raw frames of position NNN (with --keep-frames)
//! DIR/hdr/NNN.exr            HDR radiance (DN/s) of position NNN
//! DIR/truth/NNN.exr          noise-free signal rate (with --save-truth, simulator only)
//! DIR/brdf.binary            the measured table (MERL format)
//! DIR/counts.bin             samples per bin and channel (u32, MERL order)
//! DIR/report.json            timings, sample counts, coverage, validation, faults
//! DIR/previews/contact_sheet.png   measured vs re-rendered (log scale)
//! ```

use anyhow::{bail, Context, Result};
use binning::forward::{compare, lamp_constant_from_reference, rerender, ImageError};
use binning::{BinAssignment, ForwardOptions, PositionSamples, Rates, SphereView};
use clap::{Args, ValueEnum};
use gantry_hal::{BayerFrame, HalError, Rig};
use hdr::{DefectMap, HdrImage, MergeOptions};
use serde::{Deserialize, Serialize};
use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

/// Exposure strategy.
#[derive(ValueEnum, Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Bracketing {
    /// The seed's 18 exposures, 40 µs to 20 s, at every position.
    Full,
    /// Exposures chosen from the previous position's radiance range.
    Adaptive,
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
    /// Number of lamp positions over the half circle (the seed: 330).
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
    pub bracketing: Bracketing,
    /// Continue a job that was interrupted.
    #[arg(long)]
    pub resume: bool,
    /// Also write the simulator's noise-free signal rate per position (DIR/truth/NNN.exr).
    #[arg(long)]
    pub save_truth: bool,
    /// Keep the raw frames (DIR/frames/), so that `gantry rebin` can re-run the HDR merge.
    #[arg(long)]
    pub keep_frames: bool,
    /// Memory budget of the binning pass, MiB.
    #[arg(long, default_value_t = 512)]
    pub memory_mb: usize,
    /// Which bin a BRDF sample goes to: the nearest grid node (where a table value is read as the
    /// BRDF, as `tabulate` does), or the MERL reference reader's truncated indices.
    #[arg(long, value_enum, default_value = "nearest-node")]
    pub bin_assignment: BinAssignmentArg,
    /// Also fill the table by the seed's inverse mapping (§3.5), as `rebin --inverse` does.
    #[arg(long)]
    pub inverse: bool,
    /// Measure only the lamp constant, with a diffuse white standard of this albedo mounted in
    /// place of the sample; writes DIR/lamp_constant.json for later `--lamp-constant`.
    #[arg(long)]
    pub white_reference: Option<f64>,
    /// Stop after this many new positions (for tests of interrupted jobs).
    #[arg(long, hide = true)]
    pub stop_after: Option<usize>,
}

/// Arguments of `gantry rebin`.
#[derive(Args, Debug, Clone)]
pub struct RebinArgs {
    /// Directory of a finished (or interrupted) capture.
    pub dir: PathBuf,
    /// Memory budget of the binning pass, MiB.
    #[arg(long, default_value_t = 512)]
    pub memory_mb: usize,
    /// Also fill the table by the seed's inverse mapping (§3.5) from the stored HDR images:
    /// writes DIR/brdf_inverse.binary (the bins forward binning reached), DIR/brdf_inverse_all.binary
    /// (every bin reached) and DIR/inverse_report.json.
    #[arg(long)]
    pub inverse: bool,
}

/// DIR/inverse_report.json: the inverse-mapped table against the forward-binned one and, on the
/// simulator, against the truth.
#[derive(Debug, Serialize)]
struct InverseReport {
    positions: usize,
    /// Coverage of brdf_inverse.binary: the bins forward binning also reached.
    coverage: f64,
    /// Coverage of brdf_inverse_all.binary: every bin some position reaches.
    coverage_all: f64,
    wall_seconds: f64,
    versus_forward: TableError,
    truth_table_error: Option<TableError>,
    reciprocal_truth_error: Option<TableError>,
    all_bins_truth_table_error: Option<TableError>,
    all_bins_reciprocal_truth_error: Option<TableError>,
}

/// `rebin --inverse`: the seed's inverse mapping over the stored HDR images.
fn inverse_mapping(
    paths: &Paths,
    spec: &JobSpec,
    ctx: &JobContext<'_>,
    truth: Option<(&brdf::MerlTable, &brdf::MerlTable)>,
) -> Result<()> {
    let t0 = Instant::now();
    let opts = binning::inverse::InverseOptions::default();
    let mut positions = Vec::with_capacity(spec.angles_deg.len());
    for (i, &angle) in spec.angles_deg.iter().enumerate() {
        let path = hdr::hdr_path(&paths.root, i);
        let file = hdr::read_exr(&path)?;
        let valid = file
            .valid
            .clone()
            .unwrap_or_else(|| vec![true; file.radiance.len()]);
        let rates = Rates {
            rate: &file.radiance,
            valid: &valid,
        };
        let mut p =
            binning::inverse::InversePosition::new(ctx.calibration, ctx.view, angle, rates, &opts)
                .with_context(|| format!("{}", path.display()))?;
        if let Some(a) = ctx.ambient {
            p.ambient = a;
        }
        positions.push(p);
    }
    let filled = binning::inverse::fill_table(
        ctx.calibration,
        ctx.view,
        &positions,
        &ctx.lamp_constant,
        &opts,
    )?;
    // Quality guard: bins that no pixel's own configuration reached (the forward table has no
    // sample there) lie at the specular peak or at grazing angles, where interpolating between
    // pixels does not resolve the BRDF; they are kept only in brdf_inverse_all.binary.
    let forward = brdf::merl::read(paths.root.join("brdf.binary"))?;
    let mut guarded = filled.table.clone();
    for c in 0..3 {
        for b in 0..brdf::table::BINS {
            if !forward.is_valid(c, b) {
                guarded.set(c, b, -1.0);
            }
        }
    }
    let out = paths.root.join("brdf_inverse.binary");
    brdf::merl::write(&out, &guarded)?;
    brdf::merl::write(paths.root.join("brdf_inverse_all.binary"), &filled.table)?;
    let covered = |t: &brdf::MerlTable| {
        (0..3)
            .map(|c| (0..brdf::table::BINS).filter(|&b| t.is_valid(c, b)).count())
            .sum::<usize>() as f64
            / (3 * brdf::table::BINS) as f64
    };
    let report = InverseReport {
        positions: positions.len(),
        coverage: covered(&guarded),
        coverage_all: filled.coverage(),
        wall_seconds: t0.elapsed().as_secs_f64(),
        versus_forward: table_error(&guarded, &forward),
        truth_table_error: truth.map(|(t, _)| table_error(&guarded, t)),
        reciprocal_truth_error: truth.map(|(_, r)| table_error(&guarded, r)),
        all_bins_truth_table_error: truth.map(|(t, _)| table_error(&filled.table, t)),
        all_bins_reciprocal_truth_error: truth.map(|(_, r)| table_error(&filled.table, r)),
    };
    write_json(&paths.root.join("inverse_report.json"), &report)?;
    println!(
        "wrote {} (coverage {:.1}%, {:.0} s; vs forward table: median |log| {:.4}{})",
        out.display(),
        100.0 * report.coverage,
        report.wall_seconds,
        report.versus_forward.median_abs_log,
        match (&report.truth_table_error, &report.reciprocal_truth_error) {
            (Some(t), Some(r)) => format!(
                "; vs truth: median |log| {:.4}, p90 {:.4} (symmetrised truth: {:.4}, p90 {:.4})",
                t.median_abs_log, t.p90_abs_log, r.median_abs_log, r.p90_abs_log
            ),
            _ => String::new(),
        }
    );
    Ok(())
}

/// The parameters that determine a job's result; stored as DIR/job.json.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
struct JobSpec {
    version: u32,
    backend: String,
    material: String,
    positions: usize,
    scale: f64,
    seed: u64,
    faults: bool,
    bracketing: Bracketing,
    keep_frames: bool,
    angles_deg: Vec<f64>,
    /// Jobs written before this field existed binned with the reference reader's indexing.
    #[serde(default = "reference_reader")]
    bin_assignment: BinAssignment,
}

fn reference_reader() -> BinAssignment {
    BinAssignment::ReferenceReader
}

/// What happened at one position; stored as DIR/positions/NNN.json.
#[derive(Debug, Clone, Default, Serialize, Deserialize)]
struct PositionLog {
    index: usize,
    angle_deg: f64,
    exposures_s: Vec<f64>,
    samples: usize,
    valid_pixels: usize,
    series_attempts: usize,
    faults: Vec<String>,
    sim_time_s: f64,
    wall_s: f64,
}

/// DIR/report.json.
#[derive(Debug, Clone, Serialize)]
struct Report {
    material: String,
    backend: String,
    geometry: String,
    positions: usize,
    wall_seconds: Stages,
    simulated_capture_s: Option<f64>,
    simulated_capture_hours: Option<f64>,
    samples_total: u64,
    samples_per_position_median: usize,
    coverage: f64,
    binning_passes: usize,
    lamp_constant: [f64; 3],
    hot_pixels: usize,
    validation: Vec<PositionValidation>,
    validation_median_abs_log: f64,
    faults: FaultSummary,
    truth_table_error: Option<TableError>,
    /// Error against the reciprocity-symmetrised truth, ½(f(φd) + f(φd + π)): what a reciprocal
    /// measurement can see when the true material (a neural fit) is not exactly reciprocal.
    reciprocal_truth_error: Option<TableError>,
}

#[derive(Debug, Clone, Default, Serialize)]
struct Stages {
    setup: f64,
    capture: f64,
    binning: f64,
    validation: f64,
    total: f64,
}

#[derive(Debug, Clone, Serialize)]
struct PositionValidation {
    index: usize,
    angle_deg: f64,
    #[serde(flatten)]
    error: ImageError,
}

#[derive(Debug, Clone, Default, Serialize)]
struct FaultSummary {
    total: usize,
    repeated_series: usize,
    by_kind: std::collections::BTreeMap<String, usize>,
    events: Vec<String>,
}

/// Error of the measured table against the simulator's true material over covered bins.
#[derive(Debug, Clone, Serialize)]
pub struct TableError {
    /// Bins (× channels) compared.
    pub bins: usize,
    /// Median |ln(measured / true)|.
    pub median_abs_log: f64,
    /// 90th percentile of |ln(measured / true)|.
    pub p90_abs_log: f64,
}

struct Paths {
    root: PathBuf,
}

impl Paths {
    fn job(&self) -> PathBuf {
        self.root.join("job.json")
    }
    fn calibration(&self) -> PathBuf {
        self.root.join("calibration.json")
    }
    fn ambient(&self) -> PathBuf {
        self.root.join("ambient.json")
    }
    fn lamp_constant(&self) -> PathBuf {
        self.root.join("lamp_constant.json")
    }
    fn defects(&self) -> PathBuf {
        self.root.join("defects.json")
    }
    fn samples(&self, i: usize) -> PathBuf {
        self.root.join("positions").join(format!("{i:03}.samples"))
    }
    fn log(&self, i: usize) -> PathBuf {
        self.root.join("positions").join(format!("{i:03}.json"))
    }
    fn frames(&self, i: usize) -> PathBuf {
        self.root.join("frames").join(format!("{i:03}.frames"))
    }
}

fn write_atomic(path: &Path, bytes: &[u8]) -> Result<()> {
    if let Some(parent) = path.parent() {
        std::fs::create_dir_all(parent)
            .with_context(|| format!("cannot create {}", parent.display()))?;
    }
    brdf::write_atomic(path, bytes)?;
    Ok(())
}

fn write_json<T: Serialize>(path: &Path, value: &T) -> Result<()> {
    let mut text = serde_json::to_vec_pretty(value)?;
    text.push(b'\n');
    write_atomic(path, &text)
}

fn read_json<T: for<'de> Deserialize<'de>>(path: &Path) -> Result<T> {
    let text = std::fs::read(path).with_context(|| format!("{}: cannot read", path.display()))?;
    serde_json::from_slice(&text).with_context(|| format!("{}: malformed", path.display()))
}

/// Angles of `n` lamp positions from the point opposite the camera (0°) to 164.5° (the seed's
/// 330 positions 0.5° apart; fewer positions spread over the same arc).
pub fn position_angles(n: usize) -> Vec<f64> {
    const LAST: f64 = 164.5;
    match n {
        0 => Vec::new(),
        1 => vec![0.0],
        _ => (0..n).map(|i| LAST * i as f64 / (n - 1) as f64).collect(),
    }
}

/// The simulator configuration of a job.
fn sim_config(spec: &JobSpec) -> hal_sim::SimConfig {
    let mut cfg = hal_sim::SimConfig::with_scale(spec.scale);
    cfg.seed = spec.seed;
    cfg.material = spec.material.clone();
    if spec.faults {
        cfg.faults = hal_sim::FaultConfig {
            seed: spec.seed ^ 0x5eed,
            turntable_timeout: 0.01,
            camera_frame_drop: 0.01,
            lamp_dropout: 0.003,
            ..cfg.faults
        };
    }
    cfg
}

const MOVE_TIMEOUT: Duration = Duration::from_secs(600);
const FRAME_TIMEOUT: Duration = Duration::from_secs(120);
const MAX_RETRIES: usize = 8;

/// Device-level retry policy: faults are logged, handled and retried; anything else ends the job.
struct Devices<'a> {
    rig: &'a mut Rig,
    log: &'a mut Vec<String>,
}

impl Devices<'_> {
    fn note(&mut self, what: String) {
        tracing::warn!("{what}");
        self.log.push(what);
    }

    fn move_to(&mut self, angle: f64) -> Result<()> {
        for attempt in 0..MAX_RETRIES {
            match self.rig.turntable.move_to(angle, MOVE_TIMEOUT) {
                Ok(()) => {
                    let now = self.rig.turntable.angle()?;
                    if (now - angle).abs() < 1e-3 {
                        return Ok(());
                    }
                    self.note(format!(
                        "turntable-position: at {now:.4}° instead of {angle:.4}°, re-homing"
                    ));
                    self.rig.turntable.home(MOVE_TIMEOUT)?;
                }
                Err(e @ HalError::Timeout { .. }) => {
                    self.note(format!("turntable-timeout: attempt {}: {e}", attempt + 1));
                }
                Err(e @ (HalError::LostPosition { .. } | HalError::NotHomed)) => {
                    self.note(format!("turntable-lost: {e}, re-homing"));
                    self.rig.turntable.home(MOVE_TIMEOUT)?;
                }
                Err(e @ HalError::Disconnected { .. }) => {
                    self.note(format!("turntable-disconnect: {e}, reconnecting"));
                    self.rig.turntable.reconnect()?;
                    self.rig.turntable.home(MOVE_TIMEOUT)?;
                }
                Err(e) => return Err(e.into()),
            }
        }
        bail!("turntable did not reach {angle}° after {MAX_RETRIES} attempts")
    }

    fn frame(&mut self, exposure: f64) -> Result<BayerFrame> {
        for attempt in 0..MAX_RETRIES {
            let r = self
                .rig
                .camera
                .set_exposure(exposure)
                .and_then(|_| self.rig.camera.capture(FRAME_TIMEOUT));
            match r {
                Ok(f) => match f.validate() {
                    Ok(()) => return Ok(f),
                    Err(e) => self.note(format!("frame-rejected: {e}")),
                },
                Err(e @ (HalError::FrameDropped { .. } | HalError::Timeout { .. })) => {
                    self.note(format!("frame-dropped: attempt {}: {e}", attempt + 1));
                }
                Err(e @ HalError::CorruptedFrame { .. }) => {
                    self.note(format!("frame-corrupted: {e}"))
                }
                Err(e @ HalError::Disconnected { .. }) => {
                    self.note(format!("camera-disconnect: {e}, reconnecting"));
                    self.rig.camera.reconnect()?;
                }
                Err(e) => return Err(e.into()),
            }
        }
        bail!("camera gave no good frame at {exposure} s after {MAX_RETRIES} attempts")
    }

    /// Checks the lamp after a series: `Ok(false)` when the series must be repeated.
    fn lamp_ok(&mut self) -> Result<bool> {
        match self.rig.lamp.state() {
            Ok(gantry_hal::LampState::Stable) => Ok(true),
            Ok(gantry_hal::LampState::Off) => {
                self.note("lamp-off: lamp found off, relighting and repeating the series".into());
                self.rig.lamp.set_on(true)?;
                self.rig.lamp.wait_stable(Duration::from_secs(3600))?;
                Ok(false)
            }
            Ok(other) => {
                self.note(format!("lamp-unstable: {other:?}, waiting"));
                self.rig.lamp.wait_stable(Duration::from_secs(3600))?;
                Ok(false)
            }
            Err(e @ HalError::LampDropout { .. }) => {
                self.note(format!(
                    "lamp-dropout: {e}, relighting and repeating the series"
                ));
                self.rig.lamp.set_on(true)?;
                self.rig.lamp.wait_stable(Duration::from_secs(3600))?;
                Ok(false)
            }
            Err(e @ HalError::LampFlicker { .. }) => {
                self.note(format!("lamp-flicker: {e}, repeating the series"));
                self.rig.lamp.wait_stable(Duration::from_secs(3600))?;
                Ok(false)
            }
            Err(e) => Err(e.into()),
        }
    }
}

/// Largest share of well-lit sphere pixels (≥ 5 exposures) whose exposure fit may be poor
/// before a series counts as taken in changing light ([`hdr::fit_quality`]; noise alone leaves
/// a fraction of a percent).
const MAX_LOW_FIT_FRACTION: f64 = 0.03;

fn encode_frames(frames: &[BayerFrame]) -> Vec<u8> {
    let mut out = b"GBFRAME1".to_vec();
    out.extend_from_slice(&(frames.len() as u32).to_le_bytes());
    for f in frames {
        out.extend_from_slice(&(f.width as u32).to_le_bytes());
        out.extend_from_slice(&(f.height as u32).to_le_bytes());
        out.push(f.bit_depth);
        out.push(match f.pattern {
            gantry_hal::BayerPattern::Rggb => 0,
            gantry_hal::BayerPattern::Bggr => 1,
            gantry_hal::BayerPattern::Grbg => 2,
            gantry_hal::BayerPattern::Gbrg => 3,
        });
        for v in [f.exposure_s, f.timestamp_s, f.sensor_temperature_c] {
            out.extend_from_slice(&v.to_le_bytes());
        }
        out.extend_from_slice(&f.frame_number.to_le_bytes());
        for v in &f.data {
            out.extend_from_slice(&v.to_le_bytes());
        }
    }
    out
}

fn decode_frames(bytes: &[u8], path: &Path) -> Result<Vec<BayerFrame>> {
    let bad = || anyhow::anyhow!("{}: malformed frame file", path.display());
    let mut pos = 0usize;
    let mut take = |n: usize| -> Result<&[u8]> {
        let s = bytes.get(pos..pos + n).ok_or_else(bad)?;
        pos += n;
        Ok(s)
    };
    if take(8)? != b"GBFRAME1" {
        return Err(bad());
    }
    let n = u32::from_le_bytes(take(4)?.try_into()?) as usize;
    let mut frames = Vec::with_capacity(n.min(64));
    for _ in 0..n {
        let w = u32::from_le_bytes(take(4)?.try_into()?) as usize;
        let h = u32::from_le_bytes(take(4)?.try_into()?) as usize;
        let depth = take(1)?[0];
        let pattern = match take(1)?[0] {
            0 => gantry_hal::BayerPattern::Rggb,
            1 => gantry_hal::BayerPattern::Bggr,
            2 => gantry_hal::BayerPattern::Grbg,
            3 => gantry_hal::BayerPattern::Gbrg,
            _ => return Err(bad()),
        };
        let e = f64::from_le_bytes(take(8)?.try_into()?);
        let t = f64::from_le_bytes(take(8)?.try_into()?);
        let temp = f64::from_le_bytes(take(8)?.try_into()?);
        let num = u64::from_le_bytes(take(8)?.try_into()?);
        let count = w.checked_mul(h).ok_or_else(bad)?;
        let raw = take(count.checked_mul(2).ok_or_else(bad)?)?;
        let data = raw
            .chunks_exact(2)
            .map(|c| u16::from_le_bytes([c[0], c[1]]))
            .collect();
        frames.push(
            BayerFrame::new(w, h, depth, pattern, data, e, t, temp, num)
                .with_context(|| format!("{}: bad frame", path.display()))?,
        );
    }
    Ok(frames)
}

fn channel_fn(pattern: gantry_hal::BayerPattern) -> impl Fn(usize, usize) -> usize + Sync + Copy {
    move |x, y| pattern.channel_at(x, y)
}

/// Everything a position needs besides the devices.
struct JobContext<'a> {
    view: &'a SphereView,
    calibration: &'a calib::Calibration,
    defects: &'a DefectMap,
    lamp_constant: [f64; 3],
    assignment: BinAssignment,
    /// Ambient rate per channel (DN/s), measured with the lamp off; `None` for jobs from before
    /// it was measured (the shadowed side of the sphere is used then).
    ambient: Option<[f64; 3]>,
}

/// Captures one position: returns the merged HDR image, its frames and the exposures used.
fn capture_series(
    dev: &mut Devices<'_>,
    ctx: &JobContext<'_>,
    angle: f64,
    exposures: &[f64],
    attempts: &mut usize,
) -> Result<(HdrImage, Vec<BayerFrame>)> {
    dev.move_to(angle)?;
    // Frames flagged by the consistency check in the previous attempt: when a repeated series
    // flags the same frames again with a steady lamp, the deviation is in the scene (e.g. a
    // highlight crossing the valid window), not in the light, and the series is accepted.
    let mut previously_flagged: Option<Vec<usize>> = None;
    for _ in 0..MAX_RETRIES {
        *attempts += 1;
        let mut frames = Vec::with_capacity(exposures.len());
        for &e in exposures {
            frames.push(dev.frame(e)?);
        }
        if !dev.lamp_ok()? {
            continue;
        }
        let image = hdr::merge(&frames, Some(ctx.defects), &MergeOptions::default())?;
        let odd = hdr::inconsistent_frames(&hdr::check_frames(&frames, &image)?, 0.05, 200);
        if !odd.is_empty() && previously_flagged.as_ref() != Some(&odd) {
            dev.note(format!(
                "series-inconsistent: frames {odd:?} disagree with the fit (lamp change?), repeating"
            ));
            previously_flagged = Some(odd);
            continue;
        }
        let fit = hdr::fit_quality(&image, ctx.view.pixels.iter().map(|p| p.index as usize), 5);
        tracing::debug!(fitted = fit.fitted, low = fit.low_correlation, "series fit");
        if fit.low_fraction() > MAX_LOW_FIT_FRACTION {
            dev.note(
                "series-inconsistent: too many pixels fit badly (lamp change?), repeating".into(),
            );
            continue;
        }
        return Ok((image, frames));
    }
    bail!("position at {angle}°: no clean exposure series after {MAX_RETRIES} attempts")
}

/// Writes position `i`'s HDR image as DIR/hdr/NNN.exr; returns the metadata written.
fn write_hdr(
    root: &Path,
    i: usize,
    angle: f64,
    image: &HdrImage,
    frames: &[BayerFrame],
) -> Result<hdr::PositionInfo> {
    let info = hdr::PositionInfo {
        index: Some(i as u32),
        angle_deg: Some(angle),
        sensor_temperature_c: frames.first().map(|f| f.sensor_temperature_c),
        timestamp_s: frames.first().map(|f| f.timestamp_s),
    };
    hdr::write_hdr_exr(&hdr::hdr_path(root, i), image, &info, &Default::default())?;
    Ok(info)
}

fn samples_of(
    ctx: &JobContext<'_>,
    image: &HdrImage,
    index: usize,
    angle: f64,
) -> Result<PositionSamples> {
    let lamp = ctx.calibration.lamp_position(angle);
    let samples = binning::position_samples(
        ctx.view,
        Rates {
            rate: &image.radiance,
            valid: &image.valid,
        },
        &lamp,
        &ctx.lamp_constant,
        &ForwardOptions {
            assignment: ctx.assignment,
            measured_ambient: ctx.ambient,
            ..ForwardOptions::default()
        },
    )?;
    Ok(PositionSamples {
        position: index as u32,
        angle_deg: angle,
        samples,
    })
}

/// `gantry capture`.
pub fn capture(args: CaptureArgs) -> Result<()> {
    let t_start = Instant::now();
    let paths = Paths {
        root: args.out.clone(),
    };
    if args.positions == 0 {
        bail!("--positions must be at least 1");
    }
    if !(args.scale > 0.0 && args.scale <= 1.0) {
        bail!("--scale must be in (0, 1], got {}", args.scale);
    }
    let spec = JobSpec {
        version: 1,
        backend: if args.sim { "sim".into() } else { "rig".into() },
        material: args.material.clone(),
        positions: args.positions,
        scale: args.scale,
        seed: args.seed,
        faults: args.faults,
        bracketing: args.bracketing,
        keep_frames: args.keep_frames,
        angles_deg: position_angles(args.positions),
        bin_assignment: args.bin_assignment.into(),
    };
    // The devices, and the simulator behind them when `--sim`; opened before anything is written,
    // so that an absent device leaves no job behind.
    let (sim, mut rig) = if args.sim {
        let sim = hal_sim::SimRig::from_config(sim_config(&spec))
            .with_context(|| format!("cannot build the simulated rig for '{}'", spec.material))?;
        let rig = sim.rig();
        (Some(sim), rig)
    } else {
        (None, open_rig(&args)?)
    };
    if paths.job().exists() {
        if !args.resume {
            bail!(
                "{} already holds a capture: pass --resume to continue it, or choose another --out",
                args.out.display()
            );
        }
        let old: JobSpec = read_json(&paths.job())?;
        if old != spec {
            bail!(
                "{}: --resume with different parameters than the interrupted job ({})",
                args.out.display(),
                paths.job().display()
            );
        }
    } else {
        write_json(&paths.job(), &spec)?;
    }
    for sub in ["positions", "hdr", "previews"] {
        let d = args.out.join(sub);
        std::fs::create_dir_all(&d).with_context(|| format!("cannot create {}", d.display()))?;
    }
    // Calibration.
    let (calibration, geometry) = if let Some(p) = &args.calibration {
        (
            calib::Calibration::read(p)?,
            format!("file {}", p.display()),
        )
    } else if paths.calibration().exists() {
        let g = read_json::<serde_json::Value>(&paths.calibration())?
            .get("fit")
            .map_or("simulator truth", |_| "calibrated");
        (
            calib::Calibration::read(&paths.calibration())?,
            g.to_string(),
        )
    } else if let Some(sim) = &sim {
        if args.true_geometry {
            (
                calib::sim::calibration_from_truth(sim.truth())?,
                "simulator truth".to_string(),
            )
        } else {
            let (run, _, _) = crate::calibrate::calibrate_sim(
                sim_config(&spec),
                calib::TargetProtocol::for_sensor,
                spec.seed,
            )?;
            tracing::info!(
                rms_px = run.reprojection_rms(),
                "calibrated the simulated rig"
            );
            (run.calibration, "calibrated".to_string())
        }
    } else {
        bail!("with --rig pass --calibration FILE (from `gantry calibrate --rig`)");
    };
    calibration.write(&paths.calibration())?;
    tracing::info!(%geometry, "geometry");
    let info = rig.camera.info();
    if (info.width, info.height) != (calibration.camera.width, calibration.camera.height) {
        bail!(
            "the camera delivers {}x{} frames but the calibration is for {}x{}",
            info.width,
            info.height,
            calibration.camera.width,
            calibration.camera.height
        );
    }
    let view = SphereView::new(&calibration, channel_fn(info.pattern), 85.0);
    tracing::info!(pixels = view.pixels.len(), "sphere pixels");
    rig.turntable.home(MOVE_TIMEOUT)?;
    // Dark frame and defect map.
    let defects = if paths.defects().exists() {
        let hot: HotPixels = read_json(&paths.defects())?;
        hot.to_map()?
    } else {
        let dark = rig.camera.capture_dark(60.0, Duration::from_secs(300))?;
        let map = DefectMap::from_dark_frame(&dark, &hdr::DarkFrameOptions::default())?;
        write_json(&paths.defects(), &HotPixels::of(&map))?;
        map
    };
    // Ambient signal (room light and dark current) with the lamp off.
    let ambient = if paths.ambient().exists() {
        read_json::<[f64; 3]>(&paths.ambient())?
    } else {
        let a = lamp_off_ambient(&mut rig, &view, &defects)?;
        write_json(&paths.ambient(), &a)?;
        a
    };
    tracing::info!(?ambient, "ambient rate with the lamp off, DN/s");
    rig.lamp.set_on(true)?;
    rig.lamp.wait_stable(Duration::from_secs(3600))?;
    if let Some(albedo) = args.white_reference {
        // The operator has mounted a diffuse white standard: measure the lamp constant only.
        let k = white_reference(
            &mut rig,
            &calibration,
            &view,
            &defects,
            albedo,
            sim.as_ref(),
        )?;
        write_json(&args.out.join("lamp_constant.json"), &k)?;
        println!(
            "lamp constant [{:.6e}, {:.6e}, {:.6e}] written to {}",
            k[0],
            k[1],
            k[2],
            args.out.join("lamp_constant.json").display()
        );
        return Ok(());
    }
    // Absolute scale: a given lamp constant, the one stored by an interrupted job, or (simulator
    // only) a white-standard run now.
    let lamp_constant = if let Some(f) = &args.lamp_constant {
        let k = read_lamp_constant(f)?;
        write_json(&paths.lamp_constant(), &k)?;
        k
    } else if paths.lamp_constant().exists() {
        read_lamp_constant(&paths.lamp_constant())?
    } else if sim.is_some() {
        let k = white_reference_sim(&spec, &calibration, &view, &defects)?;
        write_json(&paths.lamp_constant(), &k)?;
        k
    } else {
        bail!(
            "with --rig pass --lamp-constant FILE (from `gantry capture --rig ... --white-reference ALBEDO`)"
        );
    };
    // The black level matters only to adaptive bracketing.
    let black = match spec.bracketing {
        Bracketing::Adaptive => black_level(&mut rig)?,
        Bracketing::Full => 0.0,
    };
    let ctx = JobContext {
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
    let bar = indicatif::ProgressBar::new(spec.positions as u64);
    bar.set_style(
        indicatif::ProgressStyle::with_template(
            "{spinner} [{elapsed_precise}] {bar:40} {pos}/{len} positions, ETA {eta} {msg}",
        )
        .unwrap_or_else(|_| indicatif::ProgressStyle::default_bar()),
    );
    let mut previous: Option<HdrImage> = None;
    let mut new_positions = 0usize;
    for (i, &angle) in spec.angles_deg.iter().enumerate() {
        if paths.log(i).exists() && paths.samples(i).exists() {
            bar.inc(1);
            previous = None;
            continue;
        }
        if let Some(limit) = args.stop_after {
            if new_positions >= limit {
                bar.abandon_with_message("stopped (--stop-after)");
                return Ok(());
            }
        }
        let t0 = Instant::now();
        let sim_t0 = rig.clock.now();
        if let Some(sim) = &sim {
            sim.begin_position(i as u64);
        }
        let exposures = match (spec.bracketing, &previous) {
            (Bracketing::Adaptive, Some(prev)) => {
                let roi: Vec<bool> = sphere_mask(&view);
                let opts = hdr::BracketOptions {
                    black_level_dn: black,
                    ..Default::default()
                };
                hdr::plan_exposures(Some(prev), Some(&roi), &opts)?.exposures_s
            }
            _ => hdr::seed_ladder(),
        };
        let mut log = PositionLog {
            index: i,
            angle_deg: angle,
            ..Default::default()
        };
        let mut faults = Vec::new();
        let (image, frames) = {
            let mut dev = Devices {
                rig: &mut rig,
                log: &mut faults,
            };
            capture_series(&mut dev, &ctx, angle, &exposures, &mut log.series_attempts)?
        };
        let info = write_hdr(&args.out, i, angle, &image, &frames)?;
        if let (true, Some(sim)) = (args.save_truth, &sim) {
            let t = sim.position_truth(angle);
            hdr::write_truth_exr(
                &hdr::truth_path(&args.out, i),
                image.width,
                image.height,
                &t.signal_rate_dn_per_s,
                &info,
            )?;
        }
        if spec.keep_frames {
            write_atomic(&paths.frames(i), &encode_frames(&frames))?;
        }
        let samples = samples_of(&ctx, &image, i, angle)?;
        samples.write(&paths.samples(i))?;
        log.exposures_s = exposures;
        log.samples = samples.samples.len();
        log.valid_pixels = image.valid_count();
        log.faults = faults;
        log.sim_time_s = (rig.clock.now() - sim_t0).as_secs_f64();
        log.wall_s = t0.elapsed().as_secs_f64();
        write_json(&paths.log(i), &log)?;
        previous = Some(image);
        new_positions += 1;
        bar.inc(1);
    }
    bar.finish_and_clear();
    let capture_s = t_capture.elapsed().as_secs_f64();
    finish(
        &paths,
        &spec,
        &ctx,
        info.pattern,
        args.memory_mb,
        Stages {
            setup: setup_s,
            capture: capture_s,
            ..Default::default()
        },
        t_start,
        args.inverse,
    )
}

fn sphere_mask(view: &SphereView) -> Vec<bool> {
    let mut m = vec![false; view.width * view.height];
    for p in &view.pixels {
        m[p.index as usize] = true;
    }
    m
}

/// Hot-pixel list as stored in DIR/defects.json.
#[derive(Debug, Serialize, Deserialize)]
struct HotPixels {
    width: usize,
    height: usize,
    hot: Vec<(usize, usize)>,
}

impl HotPixels {
    fn of(map: &DefectMap) -> Self {
        Self {
            width: map.width(),
            height: map.height(),
            hot: map.hot_pixels(),
        }
    }
    fn to_map(&self) -> Result<DefectMap> {
        let mut mask = vec![false; self.width * self.height];
        for &(x, y) in &self.hot {
            if x >= self.width || y >= self.height {
                bail!("defects.json: hot pixel ({x}, {y}) outside the sensor");
            }
            mask[y * self.width + x] = true;
        }
        Ok(DefectMap::from_mask(self.width, self.height, mask)?)
    }
}

/// Measures the lamp constant with a simulated diffuse white standard (albedo 0.99) in place of
/// the sample.
fn white_reference_sim(
    spec: &JobSpec,
    calibration: &calib::Calibration,
    view: &SphereView,
    defects: &DefectMap,
) -> Result<[f64; 3]> {
    const ALBEDO: f64 = 0.99;
    let mut cfg = sim_config(spec);
    cfg.material = format!("lambert:kd={ALBEDO}");
    cfg.faults = hal_sim::FaultConfig::default();
    let sim = hal_sim::SimRig::from_config(cfg)?;
    let mut rig = sim.rig();
    rig.turntable.home(MOVE_TIMEOUT)?;
    rig.lamp.set_on(true)?;
    rig.lamp.wait_stable(Duration::from_secs(3600))?;
    white_reference(&mut rig, calibration, view, defects, ALBEDO, Some(&sim))
}

/// The lamp constant from a diffuse white standard of `albedo` mounted in place of the sample:
/// HDR images at four lamp positions that light most of the visible hemisphere.
fn white_reference(
    rig: &mut Rig,
    calibration: &calib::Calibration,
    view: &SphereView,
    defects: &DefectMap,
    albedo: f64,
    sim: Option<&hal_sim::SimRig>,
) -> Result<[f64; 3]> {
    if !(albedo > 0.0 && albedo <= 1.0) {
        bail!("white-standard albedo {albedo} must be in (0, 1]");
    }
    let mut images = Vec::new();
    let mut log = Vec::new();
    for (k, angle) in [110.0, 125.0, 140.0, 155.0].into_iter().enumerate() {
        if let Some(sim) = sim {
            sim.begin_position(1_000_000 + k as u64);
        }
        let mut dev = Devices {
            rig: &mut *rig,
            log: &mut log,
        };
        dev.move_to(angle)?;
        let frames: Vec<BayerFrame> = hdr::seed_ladder()
            .into_iter()
            .map(|e| dev.frame(e))
            .collect::<Result<_>>()?;
        let image = hdr::merge(&frames, Some(defects), &MergeOptions::default())?;
        images.push((image, calibration.lamp_position(angle)));
    }
    let refs: Vec<(Rates<'_>, binning::geometry::V3)> = images
        .iter()
        .map(|(im, lamp)| {
            (
                Rates {
                    rate: &im.radiance,
                    valid: &im.valid,
                },
                *lamp,
            )
        })
        .collect();
    Ok(lamp_constant_from_reference(view, &refs, [albedo; 3])?)
}

/// The devices of `--rig rig.toml`: the real GRBL turntable, lamp and V4L2 camera for
/// `backend = "real"` (an absent device fails at once, naming it), or the simulated rig of the
/// file's `[sim]` table for `backend = "sim"`, driven exactly like real devices (no ground truth).
fn open_rig(args: &CaptureArgs) -> Result<Rig> {
    let rig_path = args
        .rig
        .as_ref()
        .context("--rig rig.toml is required without --sim")?;
    let cfg = gantry_hal::RigConfig::load(rig_path)?;
    Ok(match cfg.backend {
        gantry_hal::Backend::Real => gantry_hal::open_real_rig(&cfg)
            .with_context(|| format!("cannot open the devices of {}", rig_path.display()))?,
        gantry_hal::Backend::Sim => hal_sim::SimRig::from_rig_config(&cfg)
            .with_context(|| format!("cannot build the simulated rig of {}", rig_path.display()))?
            .rig(),
    })
}

/// Exposures of the lamp-off ambient measurement (seconds): the longest of the seed's ladder and
/// a quarter of it.
const AMBIENT_EXPOSURES_S: [f64; 2] = [20.0, 5.0];

/// The ambient signal rate per channel (DN/s): room light reaching the camera from the sphere
/// plus dark current, from two exposures with the lamp off (see
/// [`binning::forward::ambient_from_lamp_off`]). Leaves the lamp off.
fn lamp_off_ambient(rig: &mut Rig, view: &SphereView, defects: &DefectMap) -> Result<[f64; 3]> {
    rig.lamp.set_on(false)?;
    let mut log = Vec::new();
    let mut dev = Devices {
        rig: &mut *rig,
        log: &mut log,
    };
    let [long_s, short_s] = AMBIENT_EXPOSURES_S;
    let long = dev.frame(long_s)?;
    let short = dev.frame(short_s)?;
    let mask = defects.mask();
    Ok(binning::forward::ambient_from_lamp_off(
        view,
        &long.data,
        long.exposure_s,
        &short.data,
        short.exposure_s,
        &|i| !mask[i],
    )?)
}

/// A lamp constant file: three finite, positive numbers (JSON array).
fn read_lamp_constant(path: &Path) -> Result<[f64; 3]> {
    let k: [f64; 3] = read_json(path)?;
    if !k.iter().all(|v| v.is_finite() && *v > 0.0) {
        bail!(
            "{}: lamp constant {k:?} must be three finite positive numbers",
            path.display()
        );
    }
    Ok(k)
}

/// Black level of the camera (DN): the median of a frame at the shortest exposure, where dark
/// current contributes nothing and light only on the small lit part of the sphere.
fn black_level(rig: &mut Rig) -> Result<f64> {
    let min_exposure = rig.camera.info().min_exposure_s;
    let mut log = Vec::new();
    let frame = Devices { rig, log: &mut log }.frame(min_exposure)?;
    let mut v: Vec<u16> = frame.data;
    let mid = v.len() / 2;
    let (_, m, _) = v.select_nth_unstable(mid);
    Ok(*m as f64)
}

/// Binning, validation and the report (and, with `inverse`, the inverse mapping), shared by
/// capture and rebin.
#[allow(clippy::too_many_arguments)]
fn finish(
    paths: &Paths,
    spec: &JobSpec,
    ctx: &JobContext<'_>,
    pattern: gantry_hal::BayerPattern,
    memory_mb: usize,
    mut stages: Stages,
    t_start: Instant,
    inverse: bool,
) -> Result<()> {
    // On the simulator, the true table and its reciprocity-symmetrised version.
    let truth_tables = if spec.backend == "sim" {
        let m = brdf::spec::load(&spec.material)?;
        Some((m.tabulate(), reciprocal_table(&m)))
    } else {
        None
    };
    let truth = truth_tables.as_ref().map(|(t, r)| (t, r));
    let t_bin = Instant::now();
    let n = spec.angles_deg.len();
    let files: Vec<PathBuf> = (0..n).map(|i| paths.samples(i)).collect();
    for f in &files {
        if !f.exists() {
            bail!(
                "{} is missing: the capture is incomplete (run again with --resume)",
                f.display()
            );
        }
    }
    let binned = binning::bin_samples(
        &binning::SampleFiles::new(files),
        &binning::BinningOptions {
            budget_bytes: memory_mb.max(1) << 20,
            ..Default::default()
        },
    )?;
    brdf::merl::write(paths.root.join("brdf.binary"), &binned.table)?;
    let counts: Vec<u8> = binned.counts.iter().flat_map(|c| c.to_le_bytes()).collect();
    write_atomic(&paths.root.join("counts.bin"), &counts)?;
    stages.binning = t_bin.elapsed().as_secs_f64();
    // Validation: re-render every position from the table and compare with its HDR image.
    let t_val = Instant::now();
    let mut validation = Vec::with_capacity(n);
    let mut sheet_rows = Vec::new();
    let sheet_every = n.div_ceil(8).max(1);
    for (i, &angle) in spec.angles_deg.iter().enumerate() {
        let hdr_file = hdr::read_exr(&hdr::hdr_path(&paths.root, i))?;
        let valid = hdr_file
            .valid
            .clone()
            .unwrap_or_else(|| vec![true; hdr_file.radiance.len()]);
        let lamp = ctx.calibration.lamp_position(angle);
        let measured = Rates {
            rate: &hdr_file.radiance,
            valid: &valid,
        };
        // The table holds reflection only: add back the ambient signal the binning removed.
        let ambient = match ctx.ambient {
            Some(a) => a,
            None => binning::forward::ambient_rate(ctx.view, measured, &lamp)?,
        };
        let mut rendered = rerender(
            ctx.view,
            &binned.table,
            &lamp,
            &ctx.lamp_constant,
            ctx.assignment,
        );
        for (r, p) in rendered.iter_mut().zip(&ctx.view.pixels) {
            *r += ambient[p.channel as usize] as f32;
        }
        let error = compare(ctx.view, &rendered, measured)?;
        validation.push(PositionValidation {
            index: i,
            angle_deg: angle,
            error,
        });
        if i % sheet_every == 0 {
            let mut meas = vec![f32::NAN; ctx.view.width * ctx.view.height];
            for p in &ctx.view.pixels {
                let k = p.index as usize;
                meas[k] = if valid[k] {
                    hdr_file.radiance[k]
                } else {
                    f32::NAN
                };
            }
            sheet_rows.push(binning::validate::SheetRow {
                measured: meas,
                rendered: binning::validate::to_mosaic(ctx.view, &rendered),
            });
        }
    }
    let sheet = binning::validate::contact_sheet(ctx.view, &sheet_rows, channel_fn(pattern), 4.0);
    if sheet.width > 0 {
        let png = paths.root.join("previews").join("contact_sheet.png");
        write_png(&png, &sheet)?;
    }
    stages.validation = t_val.elapsed().as_secs_f64();
    // Report.
    let logs: Vec<PositionLog> = (0..n)
        .map(|i| read_json(&paths.log(i)))
        .collect::<Result<_>>()?;
    let mut faults = FaultSummary::default();
    for l in &logs {
        faults.repeated_series += l.series_attempts.saturating_sub(1);
        for f in &l.faults {
            faults.total += 1;
            let kind = f.split(':').next().unwrap_or("other").trim().to_string();
            *faults.by_kind.entry(kind).or_default() += 1;
            faults.events.push(format!("position {}: {f}", l.index));
        }
    }
    let mut per_pos: Vec<usize> = logs.iter().map(|l| l.samples).collect();
    per_pos.sort_unstable();
    let mut vmed: Vec<f64> = validation.iter().map(|v| v.error.median_abs_log).collect();
    vmed.sort_by(|a, b| a.total_cmp(b));
    let sim_total: f64 = logs.iter().map(|l| l.sim_time_s).sum();
    stages.total = t_start.elapsed().as_secs_f64();
    let report = Report {
        material: spec.material.clone(),
        backend: spec.backend.clone(),
        geometry: if ctx.calibration.fit.is_some() {
            "calibrated".into()
        } else {
            "simulator truth or given file".into()
        },
        positions: n,
        wall_seconds: stages,
        simulated_capture_s: (spec.backend == "sim").then_some(sim_total),
        simulated_capture_hours: (spec.backend == "sim").then_some(sim_total / 3600.0),
        samples_total: binned.total_samples(),
        samples_per_position_median: per_pos.get(per_pos.len() / 2).copied().unwrap_or(0),
        coverage: binned.coverage(),
        binning_passes: binned.passes,
        lamp_constant: ctx.lamp_constant,
        hot_pixels: ctx.defects.hot_count(),
        validation_median_abs_log: vmed.get(vmed.len() / 2).copied().unwrap_or(f64::NAN),
        validation,
        faults,
        truth_table_error: truth.map(|(t, _)| table_error(&binned.table, t)),
        reciprocal_truth_error: truth.map(|(_, r)| table_error(&binned.table, r)),
    };
    write_json(&paths.root.join("report.json"), &report)?;
    if let Some(e) = &report.truth_table_error {
        tracing::info!(
            median = e.median_abs_log,
            p90 = e.p90_abs_log,
            coverage = report.coverage,
            "table error against the true material"
        );
    }
    println!(
        "wrote {} ({} samples, coverage {:.1}%, validation median |log| {:.4}{})",
        paths.root.join("brdf.binary").display(),
        report.samples_total,
        100.0 * report.coverage,
        report.validation_median_abs_log,
        report
            .truth_table_error
            .as_ref()
            .map(|e| format!(
                ", table vs truth: median |log| {:.4}, p90 {:.4}",
                e.median_abs_log, e.p90_abs_log
            ))
            .unwrap_or_default()
            + &report
                .reciprocal_truth_error
                .as_ref()
                .map(|e| format!(
                    " (vs reciprocity-symmetrised truth: {:.4}, p90 {:.4})",
                    e.median_abs_log, e.p90_abs_log
                ))
                .unwrap_or_default()
    );
    if inverse {
        inverse_mapping(paths, spec, ctx, truth)?;
    }
    Ok(())
}

/// Tabulation of ½(f(θh, θd, φd) + f(θh, θd, φd + π)).
fn reciprocal_table(material: &brdf::spec::Material) -> brdf::MerlTable {
    struct Symmetrised<'a>(&'a brdf::spec::Material);
    impl brdf::Brdf for Symmetrised<'_> {
        fn eval(&self, wi: &brdf::Vec3, wo: &brdf::Vec3) -> brdf::Rgb {
            let (a, b) = (self.0.eval(wi, wo), self.0.eval(wo, wi));
            [0, 1, 2].map(|c| 0.5 * (a[c] + b[c]))
        }
        fn eval_half_diff(&self, hd: &brdf::HalfDiff) -> brdf::Rgb {
            let (a, b) = (
                self.0.eval_half_diff(hd),
                self.0.eval_half_diff(&hd.swapped()),
            );
            [0, 1, 2].map(|c| 0.5 * (a[c] + b[c]))
        }
        fn name(&self) -> String {
            self.0.name()
        }
    }
    brdf::MerlTable::tabulate(&Symmetrised(material))
}

/// Error of `measured` against `truth` over bins and channels where both have positive values.
pub fn table_error(measured: &brdf::MerlTable, truth: &brdf::MerlTable) -> TableError {
    let mut errs = Vec::new();
    for c in 0..3 {
        for b in 0..brdf::table::BINS {
            let (m, t) = (measured.get(c, b), truth.get(c, b));
            if m > 0.0 && t > 0.0 {
                errs.push((m / t).ln().abs());
            }
        }
    }
    errs.sort_by(|a, b| a.total_cmp(b));
    let q = |f: f64| {
        errs.get(((errs.len() as f64 * f) as usize).min(errs.len().saturating_sub(1)))
            .copied()
            .unwrap_or(f64::NAN)
    };
    TableError {
        bins: errs.len(),
        median_abs_log: q(0.5),
        p90_abs_log: q(0.9),
    }
}

fn write_png(path: &Path, img: &binning::validate::Rgb8Image) -> Result<()> {
    let buf = image::RgbImage::from_raw(img.width as u32, img.height as u32, img.data.clone())
        .context("contact sheet buffer")?;
    let mut bytes = Vec::new();
    buf.write_to(
        &mut std::io::Cursor::new(&mut bytes),
        image::ImageFormat::Png,
    )?;
    write_atomic(path, &bytes)
}

/// `gantry rebin`: re-runs HDR (from stored frames, when the capture kept them) and binning.
pub fn rebin(args: RebinArgs) -> Result<()> {
    let t_start = Instant::now();
    let paths = Paths {
        root: args.dir.clone(),
    };
    let spec: JobSpec = read_json(&paths.job())?;
    let calibration = calib::Calibration::read(&paths.calibration())?;
    let lamp_constant: [f64; 3] = read_json(&paths.lamp_constant())?;
    let hot: HotPixels = read_json(&paths.defects())?;
    let defects = hot.to_map()?;
    let pattern = if spec.backend == "sim" {
        hal_sim::SimRig::from_config(sim_config(&spec))?
            .rig()
            .camera
            .info()
            .pattern
    } else {
        gantry_hal::BayerPattern::Rggb
    };
    let view = SphereView::new(&calibration, channel_fn(pattern), 85.0);
    let ctx = JobContext {
        view: &view,
        calibration: &calibration,
        defects: &defects,
        lamp_constant,
        assignment: spec.bin_assignment,
        ambient: if paths.ambient().exists() {
            Some(read_json::<[f64; 3]>(&paths.ambient())?)
        } else {
            None
        },
    };
    let t_hdr = Instant::now();
    let mut remerged = 0;
    for (i, &angle) in spec.angles_deg.iter().enumerate() {
        let fp = paths.frames(i);
        if !fp.exists() {
            continue;
        }
        let bytes = std::fs::read(&fp).with_context(|| format!("{}: cannot read", fp.display()))?;
        let frames = decode_frames(&bytes, &fp)?;
        let image = hdr::merge(&frames, Some(&defects), &MergeOptions::default())?;
        write_hdr(&paths.root, i, angle, &image, &frames)?;
        samples_of(&ctx, &image, i, angle)?.write(&paths.samples(i))?;
        remerged += 1;
    }
    tracing::info!(remerged, "positions re-merged from stored frames");
    finish(
        &paths,
        &spec,
        &ctx,
        pattern,
        args.memory_mb,
        Stages {
            capture: t_hdr.elapsed().as_secs_f64(),
            ..Default::default()
        },
        t_start,
        args.inverse,
    )
}
