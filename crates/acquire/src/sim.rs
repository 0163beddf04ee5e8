//! The simulated rig (feature `sim`): how the simulator is set up for a job ([`SimSetup`]) and
//! the rig it builds ([`SimulatedRig`]), which knows the truth ([`GroundTruth`]): the true
//! material and geometry, the simulated operator's calibration and white standard.

use crate::devices::{LAMP_TIMEOUT, MOVE_TIMEOUT};
use crate::error::{AcquireError, Result};
use crate::finish::{material_truth, Truth};
use crate::setup::{white_reference, GroundTruth, Station};
use crate::spec::{Backend, JobRecord, JobSpec};
use binning::SphereView;
use hdr::DefectMap;

/// How the simulator is set up for a job: what changes its frames but not what is measured.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SimSetup {
    /// Sensor scale of the simulated camera (1 = 1300 × 1030).
    pub scale: f64,
    /// Seed of the simulator's noise and faults (and of its calibration session).
    pub seed: u64,
    /// Whether the simulator injects faults (1 % turntable timeouts, 1 % frame drops, lamp
    /// dropouts).
    pub faults: bool,
}

impl Default for SimSetup {
    /// Full sensor, seed 1, no faults.
    fn default() -> Self {
        Self {
            scale: 1.0,
            seed: 1,
            faults: false,
        }
    }
}

impl SimSetup {
    /// The default setup at sensor scale `scale`.
    pub fn with_scale(scale: f64) -> Self {
        Self {
            scale,
            ..Self::default()
        }
    }

    /// Checks the setup: a scale in (0, 1].
    pub fn validate(&self) -> Result<()> {
        if !(self.scale > 0.0 && self.scale <= 1.0) {
            return Err(AcquireError::InvalidJob(format!(
                "sensor scale must be in (0, 1], got {}",
                self.scale
            )));
        }
        Ok(())
    }

    /// The setup a simulated job's record holds (`None` for a job on devices).
    pub fn of_record(record: &JobRecord) -> Option<Self> {
        (record.backend == Backend::Sim).then_some(Self {
            scale: record.scale,
            seed: record.seed,
            faults: record.faults,
        })
    }

    /// What a job measuring `spec` on this simulator writes about itself.
    pub fn record(&self, spec: &JobSpec) -> JobRecord {
        JobRecord::new(spec, Backend::Sim, self.scale, self.seed, self.faults)
    }

    /// The simulator configuration measuring `material` (its scale, seed and faults).
    pub fn config(&self, material: &str) -> hal_sim::SimConfig {
        let mut cfg = hal_sim::SimConfig::with_scale(self.scale);
        cfg.seed = self.seed;
        cfg.material = material.to_string();
        if self.faults {
            cfg.faults = hal_sim::FaultConfig {
                seed: self.seed ^ 0x5eed,
                turntable_timeout: 0.01,
                camera_frame_drop: 0.01,
                lamp_dropout: 0.003,
                ..cfg.faults
            };
        }
        cfg
    }

    /// The Bayer pattern of the simulated camera.
    pub fn pattern(&self, material: &str) -> Result<gantry_hal::BayerPattern> {
        Ok(hal_sim::SimRig::from_config(self.config(material))?
            .rig()
            .camera
            .info()
            .pattern)
    }
}

/// Albedo of the simulated white standard.
pub const SIM_WHITE_ALBEDO: f64 = 0.99;

/// The simulated rig of a job: its devices and what the simulator knows about them.
pub struct SimulatedRig {
    sim: hal_sim::SimRig,
    setup: SimSetup,
    material: String,
}

impl SimulatedRig {
    /// The simulated rig measuring `spec`'s material with `setup`.
    pub fn new(spec: &JobSpec, setup: &SimSetup) -> Result<Self> {
        Self::with_config(spec, setup, setup.config(&spec.material))
    }

    /// The simulated rig of `spec` and `setup` built from `config` instead of
    /// [`SimSetup::config`] (other fault rates, say); the job records `setup`.
    pub fn with_config(
        spec: &JobSpec,
        setup: &SimSetup,
        config: hal_sim::SimConfig,
    ) -> Result<Self> {
        setup.validate()?;
        Ok(Self {
            sim: hal_sim::SimRig::from_config(config)?,
            setup: *setup,
            material: spec.material.clone(),
        })
    }

    /// The simulator behind the devices.
    pub fn sim(&self) -> &hal_sim::SimRig {
        &self.sim
    }

    /// The station of these devices, with the simulator's truth.
    pub fn station(self) -> Station {
        Station {
            rig: self.sim.rig(),
            simulator: Some(Box::new(self)),
        }
    }
}

impl Station {
    /// The simulated rig measuring `spec`'s material with `setup` (sensor scale, seed, faults).
    pub fn simulated(spec: &JobSpec, setup: &SimSetup) -> Result<Self> {
        Ok(SimulatedRig::new(spec, setup)?.station())
    }
}

impl GroundTruth for SimulatedRig {
    fn record(&self, spec: &JobSpec) -> JobRecord {
        self.setup.record(spec)
    }

    fn truth(&self) -> Result<Truth> {
        material_truth(&self.material)
    }

    fn true_calibration(&self) -> Result<calib::Calibration> {
        Ok(calib::calibration_from_truth(self.sim.truth())?)
    }

    fn calibrate(&self) -> Result<calib::Calibration> {
        let (run, _) = calib::calibrate_rig_session(
            self.setup.config(&self.material),
            calib::TargetProtocol::for_sensor,
            self.setup.seed,
        )?;
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
        Ok(run.calibration)
    }

    /// The lamp constant measured with a simulated diffuse white standard (albedo
    /// [`SIM_WHITE_ALBEDO`], no faults) in place of the sample.
    fn lamp_constant(
        &self,
        calibration: &calib::Calibration,
        view: &SphereView,
        defects: &DefectMap,
    ) -> Result<[f64; 3]> {
        let mut cfg = self.setup.config(&format!("lambert:kd={SIM_WHITE_ALBEDO}"));
        cfg.faults = hal_sim::FaultConfig::default();
        let white = SimulatedRig {
            sim: hal_sim::SimRig::from_config(cfg)?,
            setup: self.setup,
            material: String::new(),
        };
        let mut rig = white.sim.rig();
        rig.turntable.home(MOVE_TIMEOUT)?;
        rig.lamp.set_on(true)?;
        rig.lamp.wait_stable(LAMP_TIMEOUT)?;
        white_reference(
            &mut rig,
            calibration,
            view,
            defects,
            SIM_WHITE_ALBEDO,
            Some(&white),
        )
    }

    fn begin_position(&self, key: u64) {
        self.sim.begin_position(key);
    }

    fn signal_rate(&self, angle_deg: f64) -> Vec<f32> {
        self.sim.position_truth(angle_deg).signal_rate_dn_per_s
    }
}
