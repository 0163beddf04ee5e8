//! The simulated rig's ground truth as a calibration, and a whole calibration session run on
//! the simulated rig (feature `sim`).

use crate::error::{CalibError, CalibResult};
use crate::extrinsics::TipCorrespondence;
use crate::frames::stack_frames;
use crate::lamp::LampReading;
use crate::pipeline::CalibrationInputs;
use crate::protocol::{plan_board_poses, DigitizerProtocol, TargetProtocol};
use crate::schema::Calibration;

/// The calibration that the simulator's true geometry amounts to: camera intrinsics and pose,
/// lamp circle and sphere, in the schema of `calibration.json` (validated).
pub fn calibration_from_truth(t: &hal_sim::SceneTruth) -> CalibResult<Calibration> {
    let c = Calibration::new(t.camera, t.pose, t.lamp.circle, t.sphere);
    c.validate()?;
    Ok(c)
}

/// Measurement noise of a simulated calibration session (the hal-sim rig adds the camera's).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SessionNoise {
    /// Contact digitizer, metres (isotropic, per axis).
    pub digitizer_m: f64,
    /// Operator's location of the digitizer tip in the image, pixels.
    pub tip_pixel_px: f64,
    /// Caliper, metres.
    pub caliper_m: f64,
}

impl Default for SessionNoise {
    /// 50 µm digitizer, 0.3 px tip location, 10 µm caliper.
    fn default() -> Self {
        Self {
            digitizer_m: 50e-6,
            tip_pixel_px: 0.3,
            caliper_m: 10e-6,
        }
    }
}

/// Exposure of the simulated target and flat frames, seconds (white squares at ~80 % of full
/// scale on the default sensor).
pub const TARGET_EXPOSURE_S: f64 = 0.5;

/// A calibration session run on the simulated rig.
#[derive(Debug, Clone)]
pub struct SimulatedSession {
    /// What the operator would have collected.
    pub inputs: CalibrationInputs,
    /// The rig's true geometry.
    pub truth: Calibration,
    /// True pixel positions of the inner corners in every target image.
    pub true_corners: Vec<Vec<[f64; 2]>>,
}

/// The operator session of a simulated rig built from `config` (a grey Lambertian sample
/// mounted; calibration does not look at it): the target protocol `protocol` gives for the
/// sensor width, the default digitizer protocol and session noise, seeded — the one simulated
/// calibration that the capture job and `gantry calibrate --sim` share.
pub fn simulate_rig_session(
    config: hal_sim::SimConfig,
    protocol: impl FnOnce(usize) -> TargetProtocol,
    seed: u64,
) -> CalibResult<SimulatedSession> {
    let sample = std::sync::Arc::new(brdf::analytic::Lambert { kd: [0.5; 3] });
    let rig = hal_sim::SimRig::new(config, sample)
        .map_err(|e| CalibError::Invalid(format!("simulator: {e}")))?;
    let protocol = protocol(rig.truth().camera.width);
    simulate_session(
        &rig,
        &protocol,
        &DigitizerProtocol::default(),
        &SessionNoise::default(),
        seed,
    )
}

/// The simulated rig of `config` calibrated the way an operator would: the session of
/// [`simulate_rig_session`], fitted with the default options. Returns the fitted run and the
/// session (its inputs and the rig's true geometry). The one simulated calibration of the
/// workspace: the capture job's (`acquire`) and `gantry calibrate --sim`'s.
pub fn calibrate_rig_session(
    config: hal_sim::SimConfig,
    protocol: impl FnOnce(usize) -> TargetProtocol,
    seed: u64,
) -> CalibResult<(crate::CalibrationRun, SimulatedSession)> {
    let session = simulate_rig_session(config, protocol, seed)?;
    let run = crate::calibrate(&session.inputs, &crate::CalibrationOptions::default())?;
    Ok((run, session))
}

/// Runs the calibration session of `target` and `digitizer` on the simulated `rig`, seeded: the
/// board poses of [`plan_board_poses`], each exposed `frames_per_view` times and stacked; the
/// flat frames (a diffuser at the white squares' radiance); the digitizer readings and the
/// caliper diameter with `noise`.
pub fn simulate_session(
    rig: &hal_sim::SimRig,
    target: &TargetProtocol,
    digitizer: &DigitizerProtocol,
    noise: &SessionNoise,
    seed: u64,
) -> CalibResult<SimulatedSession> {
    let sim_error = |e: hal_sim::SimError| CalibError::Invalid(format!("simulator: {e}"));
    let truth = calibration_from_truth(rig.truth())?;
    let board = hal_sim::Checkerboard {
        squares_x: target.board.squares_x,
        squares_y: target.board.squares_y,
        square_m: target.board.square_m,
        ..hal_sim::Checkerboard::default()
    };
    let mut frames = Vec::with_capacity(target.views);
    let mut true_corners = Vec::with_capacity(target.views);
    for p in plan_board_poses(target, &truth.camera, seed.wrapping_add(100))? {
        let pose = hal_sim::TargetPose {
            rotation: p.rotation,
            translation: p.translation,
        };
        let caps = rig
            .capture_checkerboard_frames(&board, &pose, TARGET_EXPOSURE_S, target.frames_per_view)
            .map_err(sim_error)?;
        let corners = caps[0]
            .corners_px
            .iter()
            .map(|c| c.ok_or_else(|| CalibError::Invalid("a corner is behind the camera".into())))
            .collect::<CalibResult<Vec<_>>>()?;
        true_corners.push(corners);
        let exposures: Vec<_> = caps.into_iter().map(|c| c.frame).collect();
        frames.push(stack_frames(&exposures)?);
    }
    let white = board.white * board.irradiance / std::f64::consts::PI;
    let flat_frames = rig
        .capture_flat_frames(white, TARGET_EXPOSURE_S, target.flat_frames)
        .map_err(sim_error)?;
    let mut dig = rig.digitizer(noise.digitizer_m, seed.wrapping_add(200));
    let tips = dig
        .tip_observations(digitizer.tips, digitizer.tip_depth_m, noise.tip_pixel_px)
        .into_iter()
        .map(|o| TipCorrespondence {
            world: o.measured,
            pixel: o.pixel,
        })
        .collect();
    let lamp = dig
        .lamp_positions(&digitizer.lamp_angles_deg)
        .into_iter()
        .zip(&digitizer.lamp_angles_deg)
        .map(|(p, &a)| LampReading {
            angle_deg: a,
            position: p,
        })
        .collect();
    let sphere_points = dig.sphere_surface(digitizer.sphere_points);
    // The caliper: one reading along a line, with its own Gaussian noise.
    let mut caliper = rig.digitizer(noise.caliper_m, seed.wrapping_add(300));
    let sphere_diameter_m = caliper.measure([2.0 * truth.sphere.radius, 0.0, 0.0])[0];
    Ok(SimulatedSession {
        inputs: CalibrationInputs {
            board: target.board,
            target_frames: frames,
            flat_frames,
            tips,
            lamp,
            sphere_points,
            sphere_diameter_m,
        },
        truth,
        true_corners,
    })
}
