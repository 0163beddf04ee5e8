//! The devices of a job ([`Station`]) and what is measured once before the positions: the
//! geometry, the dark frame, the lamp-off ambient signal, the lamp constant and the black level.

use crate::devices::{Devices, MOVE_TIMEOUT};
use crate::error::{AcquireError, Result};
use crate::spec::JobSpec;
use binning::{Rates, SphereView};
use gantry_hal::{BayerFrame, Rig};
use hdr::{DefectMap, MergeOptions};
use std::path::{Path, PathBuf};
use std::time::Duration;

/// The devices a job runs on, and the simulator behind them when they are simulated with ground
/// truth.
pub struct Station {
    /// Turntable, lamp, camera and clock.
    pub rig: Rig,
    /// The simulated rig, when the devices are the simulator's and its truth may be used.
    pub sim: Option<hal_sim::SimRig>,
}

impl Station {
    /// The simulated rig of `spec` (its material, sensor scale, seed and faults).
    pub fn simulated(spec: &JobSpec) -> Result<Self> {
        let sim = hal_sim::SimRig::from_config(spec.sim_config())?;
        Ok(Self {
            rig: sim.rig(),
            sim: Some(sim),
        })
    }

    /// Devices opened by the caller (no ground truth).
    pub fn devices(rig: Rig) -> Self {
        Self { rig, sim: None }
    }

    /// The devices a rig configuration file names: the real GRBL turntable, lamp and camera for
    /// `backend = "real"` (an absent device fails at once, naming it), or the simulated rig of
    /// the file's `[sim]` table for `backend = "sim"`, driven exactly like real devices (no
    /// ground truth).
    pub fn from_rig_file(path: &Path) -> Result<Self> {
        let cfg = gantry_hal::RigConfig::load(path)?;
        let rig = match cfg.backend {
            gantry_hal::Backend::Real => gantry_hal::open_real_rig(&cfg)?,
            gantry_hal::Backend::Sim => hal_sim::SimRig::from_rig_config(&cfg)?.rig(),
        };
        Ok(Self::devices(rig))
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

/// The calibration of a simulated rig from a simulated operator session: calib's target and
/// digitizer protocol for the sensor, the session's noise, seeded. Returns the fitted run.
pub fn calibrate_simulated(config: hal_sim::SimConfig, seed: u64) -> Result<calib::CalibrationRun> {
    let session =
        calib::sim::simulate_rig_session(config, calib::TargetProtocol::for_sensor, seed)?;
    Ok(calib::calibrate(
        &session.inputs,
        &calib::CalibrationOptions::default(),
    )?)
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
/// [`binning::forward::ambient_from_lamp_off`]). Leaves the lamp off.
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
    Ok(binning::forward::ambient_from_lamp_off(
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
    sim: Option<&hal_sim::SimRig>,
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
    Ok(binning::forward::lamp_constant_from_reference(
        view,
        &refs,
        [albedo; 3],
    )?)
}

/// Albedo of the simulated white standard.
pub const SIM_WHITE_ALBEDO: f64 = 0.99;

/// The lamp constant measured with a simulated diffuse white standard (albedo
/// [`SIM_WHITE_ALBEDO`], no faults) in place of the sample of `spec`.
pub fn white_reference_sim(
    spec: &JobSpec,
    calibration: &calib::Calibration,
    view: &SphereView,
    defects: &DefectMap,
) -> Result<[f64; 3]> {
    let mut cfg = spec.sim_config();
    cfg.material = format!("lambert:kd={SIM_WHITE_ALBEDO}");
    cfg.faults = hal_sim::FaultConfig::default();
    let sim = hal_sim::SimRig::from_config(cfg)?;
    let mut rig = sim.rig();
    rig.turntable.home(MOVE_TIMEOUT)?;
    rig.lamp.set_on(true)?;
    rig.lamp.wait_stable(crate::devices::LAMP_TIMEOUT)?;
    white_reference(
        &mut rig,
        calibration,
        view,
        defects,
        SIM_WHITE_ALBEDO,
        Some(&sim),
    )
}
