//! One lamp position: move, bracketed exposures, HDR merge with its consistency checks, BRDF
//! samples; and the position's log.

use crate::devices::{Devices, FaultEvent, FaultKind, MAX_RETRIES};
use crate::error::{AcquireError, Result};
use binning::{BinAssignment, ForwardOptions, PositionSamples, Rates, SphereView};
use gantry_hal::BayerFrame;
use hdr::{DefectMap, HdrImage, MergeOptions};
use serde::{Deserialize, Deserializer, Serialize};
use std::path::Path;
use std::time::Instant;

/// Largest share of well-lit sphere pixels (≥ 5 exposures) whose exposure fit may be poor
/// before a series counts as taken in changing light ([`hdr::fit_quality`]; noise alone leaves
/// a fraction of a percent).
pub const MAX_LOW_FIT_FRACTION: f64 = 0.03;

/// What happened at one position; stored as `DIR/positions/NNN.json`.
#[derive(Debug, Clone, Default, Serialize, Deserialize)]
pub struct PositionLog {
    /// Position index.
    pub index: usize,
    /// Lamp angle, degrees.
    pub angle_deg: f64,
    /// Exposures of the accepted series, seconds.
    pub exposures_s: Vec<f64>,
    /// BRDF samples the position gave.
    pub samples: usize,
    /// Valid pixels of its HDR image.
    pub valid_pixels: usize,
    /// Series taken (1 when nothing had to be repeated).
    pub series_attempts: usize,
    /// Faults met and handled.
    #[serde(deserialize_with = "faults_compat")]
    pub faults: Vec<FaultEvent>,
    /// Rig-clock time the position took, seconds.
    pub sim_time_s: f64,
    /// Wall-clock time the position took, seconds.
    pub wall_s: f64,
    /// Where that wall-clock time went.
    #[serde(default)]
    pub timings: PositionTimings,
}

/// Wall-clock seconds of a position's steps (of the accepted series and every repeated one).
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize, Deserialize)]
pub struct PositionTimings {
    /// Moving and exposing: waiting for the devices (on the simulator, its rendering).
    pub devices_s: f64,
    /// HDR merges.
    pub merge_s: f64,
    /// Frame-consistency and fit-quality checks.
    pub checks_s: f64,
    /// Writing the HDR image (and the kept frames, the truth image).
    pub hdr_write_s: f64,
    /// BRDF samples of the sphere pixels.
    pub samples_s: f64,
    /// Writing the checkpoint (samples and log).
    pub checkpoint_s: f64,
    /// Whether the HDR write, the samples and the checkpoint ran on the writer thread,
    /// overlapped with the next position's capture (false in logs from before it did).
    #[serde(default)]
    pub background: bool,
}

impl PositionTimings {
    /// The processing time on the capture's critical path: the merges and checks, plus the
    /// writing steps where they did not run in the background.
    pub fn processing_s(&self) -> f64 {
        let written = self.hdr_write_s + self.samples_s + self.checkpoint_s;
        self.merge_s + self.checks_s + if self.background { 0.0 } else { written }
    }

    /// The writing steps (HDR write, BRDF samples, checkpoint), wherever they ran.
    pub fn writing_s(&self) -> f64 {
        self.hdr_write_s + self.samples_s + self.checkpoint_s
    }
}

/// Reads faults as events, or as the `"kind: detail"` strings of older logs.
fn faults_compat<'de, D: Deserializer<'de>>(d: D) -> Result<Vec<FaultEvent>, D::Error> {
    #[derive(Deserialize)]
    #[serde(untagged)]
    enum Stored {
        Event(FaultEvent),
        Text(String),
    }
    let stored = Vec::<Stored>::deserialize(d)?;
    Ok(stored
        .into_iter()
        .map(|s| match s {
            Stored::Event(e) => e,
            Stored::Text(t) => {
                let (kind, detail) = t.split_once(':').unwrap_or(("", &t));
                let kind = serde_json::from_value(serde_json::Value::String(kind.trim().into()))
                    .unwrap_or(FaultKind::SeriesInconsistent);
                FaultEvent {
                    kind,
                    attempt: None,
                    detail: detail.trim().to_string(),
                }
            }
        })
        .collect())
}

/// Everything a position needs besides the devices.
#[derive(Debug, Clone, Copy)]
pub struct PositionContext<'a> {
    /// Sphere pixels and their geometry.
    pub view: &'a SphereView,
    /// Rig geometry.
    pub calibration: &'a calib::Calibration,
    /// Hot photosites.
    pub defects: &'a DefectMap,
    /// Absolute scale per channel.
    pub lamp_constant: [f64; 3],
    /// Which bin a sample goes to.
    pub assignment: BinAssignment,
    /// Ambient rate per channel (DN/s), measured with the lamp off; `None` for jobs from before
    /// it was measured (the shadowed side of the sphere is used then).
    pub ambient: Option<[f64; 3]>,
}

/// Captures one position: moves there, takes the series, and repeats it while the lamp or the
/// frames say the light changed. Returns the merged HDR image and its frames; `attempts` counts
/// the series taken.
pub fn capture_series(
    dev: &mut Devices<'_>,
    ctx: &PositionContext<'_>,
    angle: f64,
    exposures: &[f64],
    attempts: &mut usize,
    timings: &mut PositionTimings,
) -> Result<(HdrImage, Vec<BayerFrame>)> {
    let t = Instant::now();
    dev.move_to(angle)?;
    timings.devices_s += t.elapsed().as_secs_f64();
    // Frames flagged by the consistency check in the previous attempt: when a repeated series
    // flags the same frames again with a steady lamp, the deviation is in the scene (e.g. a
    // highlight crossing the valid window), not in the light, and the series is accepted.
    let mut previously_flagged: Option<Vec<usize>> = None;
    for _ in 0..MAX_RETRIES {
        *attempts += 1;
        let t = Instant::now();
        let mut frames = Vec::with_capacity(exposures.len());
        for &e in exposures {
            frames.push(dev.frame(e)?);
        }
        let lamp_ok = dev.lamp_ok()?;
        timings.devices_s += t.elapsed().as_secs_f64();
        if !lamp_ok {
            continue;
        }
        let t = Instant::now();
        let image = hdr::merge(&frames, Some(ctx.defects), &MergeOptions::default())?;
        timings.merge_s += t.elapsed().as_secs_f64();
        let t = Instant::now();
        let odd = hdr::inconsistent_frames(&hdr::check_frames(&frames, &image)?, 0.05, 200);
        if !odd.is_empty() && previously_flagged.as_ref() != Some(&odd) {
            timings.checks_s += t.elapsed().as_secs_f64();
            dev.note(
                FaultKind::SeriesInconsistent,
                None,
                format!("frames {odd:?} disagree with the fit (lamp change?), repeating"),
            );
            previously_flagged = Some(odd);
            continue;
        }
        let fit = hdr::fit_quality(&image, ctx.view.pixels.iter().map(|p| p.index as usize), 5);
        timings.checks_s += t.elapsed().as_secs_f64();
        tracing::debug!(fitted = fit.fitted, low = fit.low_correlation, "series fit");
        if fit.low_fraction() > MAX_LOW_FIT_FRACTION {
            dev.note(
                FaultKind::SeriesInconsistent,
                None,
                "too many pixels fit badly (lamp change?), repeating".into(),
            );
            continue;
        }
        return Ok((image, frames));
    }
    Err(AcquireError::RetriesExhausted(format!(
        "position at {angle}°: no clean exposure series after {MAX_RETRIES} attempts"
    )))
}

/// The metadata of position `i`'s HDR image: index, lamp angle, and the sensor temperature and
/// time of its first frame.
pub fn position_info(i: usize, angle: f64, frames: &[BayerFrame]) -> hdr::PositionInfo {
    hdr::PositionInfo {
        index: Some(i as u32),
        angle_deg: Some(angle),
        sensor_temperature_c: frames.first().map(|f| f.sensor_temperature_c),
        timestamp_s: frames.first().map(|f| f.timestamp_s),
    }
}

/// Writes position `i`'s HDR image with its metadata as `DIR/hdr/NNN.exr`.
pub fn write_hdr(root: &Path, i: usize, image: &HdrImage, info: &hdr::PositionInfo) -> Result<()> {
    // Run-length encoding: the sphere's noisy floats barely compress, and ZIP took most of a
    // position's processing time (326 ms of 535 ms at full size); RLE still folds the black
    // background.
    let opts = hdr::ExrOptions {
        compression: hdr::ExrCompression::Rle,
        ..Default::default()
    };
    hdr::write_hdr_exr(&hdr::hdr_path(root, i), image, info, &opts)?;
    Ok(())
}

/// The BRDF samples of position `index` at `angle` degrees from its HDR image.
pub fn samples_of(
    ctx: &PositionContext<'_>,
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

/// Mask of the sphere pixels that give BRDF samples with the lamp at `angle` degrees: lit at
/// no more than `max_incidence_deg` from the normal (the view angle is already limited by the
/// [`SphereView`]). The region of interest of adaptive bracketing: the pixels facing away from
/// the lamp only need the long exposures, and they give no samples.
pub fn lit_mask(
    view: &SphereView,
    calibration: &calib::Calibration,
    angle: f64,
    max_incidence_deg: f64,
) -> Vec<bool> {
    let lamp = calibration.lamp_position(angle);
    let cos_max = max_incidence_deg.to_radians().cos();
    let mut m = vec![false; view.width * view.height];
    for p in &view.pixels {
        let to_lamp = (lamp - p.point).normalize();
        if p.normal.dot(&to_lamp) >= cos_max {
            m[p.index as usize] = true;
        }
    }
    m
}
