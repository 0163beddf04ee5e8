//! The devices of a job ([`Station`]), what a simulator knows about them ([`GroundTruth`]), and what is measured once before the positions: the
//! geometry, the dark frame, the lamp-off ambient signal, the lamp constant and the black level.

use crate::devices::Devices;
use crate::error::{AcquireError, Result};
use crate::finish::Truth;
use crate::spec::{JobRecord, JobSpec};
use binning::{Rates, SphereView};
use gantry_hal::{BayerFrame, Rig};
use hdr::{DefectMap, MergeOptions};
use std::path::{Path, PathBuf};
use std::time::Duration;

/// What a simulator knows about the rig it simulates, which a job on real devices cannot know:
/// the true material and geometry, and how to run the operator's steps (calibration, white
/// standard) on it. A job asks it, whatever the simulator is.
pub trait GroundTruth {
    /// What a job measuring `spec` on this simulator writes about itself (`job.json`).
    fn record(&self, spec: &JobSpec) -> JobRecord;
    /// The true table of the sample and its reciprocity-symmetrised version, for the report's
    /// error against truth.
    fn truth(&self) -> Result<Truth>;
    /// The rig's true geometry as a calibration.
    fn true_calibration(&self) -> Result<calib::Calibration>;
    /// The rig calibrated as an operator would calibrate it (target and digitizer session).
    fn calibrate(&self) -> Result<calib::Calibration>;
    /// The lamp constant measured with a white standard in place of the sample.
    fn lamp_constant(
        &self,
        calibration: &calib::Calibration,
        view: &SphereView,
        defects: &DefectMap,
    ) -> Result<[f64; 3]>;
    /// Restarts the noise and fault streams for the step `key` (a position index), so that a
    /// resumed job captures the frames an uninterrupted one would.
    fn begin_position(&self, key: u64);
    /// The noise-free signal rate (DN/s per pixel) at lamp angle `angle_deg`.
    fn signal_rate(&self, angle_deg: f64) -> Vec<f32>;
}

/// The devices a job runs on, and the simulator behind them when they are simulated with ground
/// truth.
pub struct Station {
    /// Turntable, lamp, camera and clock.
    pub rig: Rig,
    /// The simulator, when the devices are a simulator's and its truth may be used.
    pub simulator: Option<Box<dyn GroundTruth>>,
}

impl Station {
    /// Devices opened by the caller (no ground truth).
    pub fn devices(rig: Rig) -> Self {
        Self {
            rig,
            simulator: None,
        }
    }

    /// The devices a rig configuration file names: the real GRBL turntable, lamp and camera for
    /// `backend = "real"` (an absent device fails at once, naming it), or (feature `sim`) the
    /// simulated rig of the file's `[sim]` table for `backend = "sim"`, driven exactly like
    /// real devices (no ground truth).
    pub fn from_rig_file(path: &Path) -> Result<Self> {
        let cfg = gantry_hal::RigConfig::load(path)?;
        let rig = match cfg.backend {
            gantry_hal::Backend::Real => gantry_hal::open_real_rig(&cfg)?,
            #[cfg(feature = "sim")]
            gantry_hal::Backend::Sim => hal_sim::SimRig::from_rig_config(&cfg)?.rig(),
            #[cfg(not(feature = "sim"))]
            gantry_hal::Backend::Sim => {
                return Err(gantry_hal::HalError::FeatureMissing {
                    feature: "sim",
                    what: format!("the simulated rig of {}", path.display()),
                }
                .into())
            }
        };
        Ok(Self::devices(rig))
    }

    /// What a job measuring `spec` on this station writes about itself.
    pub fn record(&self, spec: &JobSpec) -> JobRecord {
        match &self.simulator {
            Some(sim) => sim.record(spec),
            None => JobRecord::on_devices(spec),
        }
    }
}

/// Where the job's geometry comes from.
#[derive(Debug, Clone, PartialEq, Eq, Default)]
pub enum CalibrationSource {
    /// A calibration file (from `calib`, or converted from OpenCV).
    File(PathBuf),
    /// The simulator's true geometry (simulator only).
    TrueGeometry,
    /// Calibrate now: on the simulator, a simulated target and digitizer session (calib's
    /// protocol for this sensor); on devices this is an error (calibrate first).
    #[default]
    Calibrate,
}

/// Exposures of the lamp-off ambient measurement (seconds): the longest of the thesis's ladder
/// and a quarter of it.
pub const AMBIENT_EXPOSURES_S: [f64; 2] = [20.0, 5.0];

/// The dark frame (60 s, lamp state unchanged) and its defect map.
pub fn dark_frame_defects(rig: &mut Rig) -> Result<DefectMap> {
    let dark = rig.camera.capture_dark(60.0, Duration::from_secs(300))?;
    Ok(DefectMap::from_dark_frame(
        &dark,
        &hdr::DarkFrameOptions::default(),
    )?)
}

/// The ambient signal rate per channel (DN/s): room light reaching the camera from the sphere
/// plus dark current, from two exposures with the lamp off (see
/// [`binning::ambient_from_lamp_off`]). Leaves the lamp off.
pub fn lamp_off_ambient(rig: &mut Rig, view: &SphereView, defects: &DefectMap) -> Result<[f64; 3]> {
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
    Ok(binning::ambient_from_lamp_off(
        view,
        &long.data,
        long.exposure_s,
        &short.data,
        short.exposure_s,
        &|i| !mask[i],
    )?)
}

/// Black level of the camera (DN): the median of a frame at the shortest exposure, where dark
/// current contributes nothing and light only on the small lit part of the sphere.
pub fn black_level(rig: &mut Rig) -> Result<f64> {
    let min_exposure = rig.camera.info().min_exposure_s;
    let mut log = Vec::new();
    let frame = Devices { rig, log: &mut log }.frame(min_exposure)?;
    let mut v: Vec<u16> = frame.data;
    let mid = v.len() / 2;
    let (_, m, _) = v.select_nth_unstable(mid);
    Ok(*m as f64)
}

/// Lamp angles of the white-standard run, degrees: four positions that light most of the
/// visible hemisphere.
pub const WHITE_REFERENCE_ANGLES_DEG: [f64; 4] = [110.0, 125.0, 140.0, 155.0];

/// The lamp constant from a diffuse white standard of `albedo` mounted in place of the sample:
/// HDR images at [`WHITE_REFERENCE_ANGLES_DEG`]. The lamp must be on and stable.
pub fn white_reference(
    rig: &mut Rig,
    calibration: &calib::Calibration,
    view: &SphereView,
    defects: &DefectMap,
    albedo: f64,
    sim: Option<&dyn GroundTruth>,
) -> Result<[f64; 3]> {
    if !(albedo > 0.0 && albedo <= 1.0) {
        return Err(AcquireError::InvalidJob(format!(
            "white-standard albedo {albedo} must be in (0, 1]"
        )));
    }
    let mut images = Vec::new();
    let mut log = Vec::new();
    for (k, angle) in WHITE_REFERENCE_ANGLES_DEG.into_iter().enumerate() {
        if let Some(sim) = sim {
            sim.begin_position(1_000_000 + k as u64);
        }
        let mut dev = Devices {
            rig: &mut *rig,
            log: &mut log,
        };
        dev.move_to(angle)?;
        let frames: Vec<BayerFrame> = hdr::thesis_ladder()
            .into_iter()
            .map(|e| dev.frame(e))
            .collect::<Result<_>>()?;
        let image = hdr::merge(&frames, Some(defects), &MergeOptions::default())?;
        images.push((image, calibration.lamp_position(angle)));
    }
    let refs: Vec<(Rates<'_>, binning::V3)> = images
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
    Ok(binning::lamp_constant_from_reference(
        view,
        &refs,
        [albedo; 3],
    )?)
}
