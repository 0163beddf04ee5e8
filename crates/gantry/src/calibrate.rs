//! `gantry calibrate`: geometric calibration of camera, lamp circle and sphere (seed §3.2).
//!
//! On the simulated rig the inputs are produced the way an operator would: checkerboard images
//! in varied poses, about 30 digitizer tip / pixel correspondences, about 30 digitized lamp
//! positions, about 30 digitized points on the sphere and a caliper diameter, all with noise.

use anyhow::{bail, Context, Result};
use calib::{Calibration, CalibrationInputs, CalibrationOptions, LampReading, TipCorrespondence};
use clap::Args;
use rand::{Rng, SeedableRng};
use std::path::PathBuf;
use std::sync::Arc;

/// Arguments of `gantry calibrate`.
#[derive(Args, Debug)]
pub struct CalibrateArgs {
    /// Calibrate the simulated rig (and write its truth beside the result).
    #[arg(long, required_unless_present = "rig", conflicts_with = "rig")]
    pub sim: bool,
    /// Calibrate real devices described by this rig configuration.
    #[arg(long)]
    pub rig: Option<PathBuf>,
    /// Output directory.
    #[arg(long)]
    pub out: PathBuf,
    /// Sensor scale of the simulated camera.
    #[arg(long, default_value_t = 1.0)]
    pub scale: f64,
    /// Number of checkerboard images (the target protocol's default: 30).
    #[arg(long, default_value_t = 30)]
    pub views: usize,
    /// Seed of the simulator and of the measurement noise.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
}

/// Digitizer noise (m), operator's tip location in the image (px), caliper noise (m).
const DIGITIZER_M: f64 = 50e-6;
const TIP_PIXEL_PX: f64 = 0.3;
const CALIPER_M: f64 = 10e-6;

/// Calibration inputs measured on the simulated rig, and the rig's true geometry.
pub fn simulated_inputs(
    config: hal_sim::SimConfig,
    views: usize,
    seed: u64,
) -> Result<(CalibrationInputs, Calibration)> {
    let rig = hal_sim::SimRig::new(config, Arc::new(brdf::analytic::Lambert { kd: [0.5; 3] }))?;
    let truth = crate::capture::calibration_from_truth(rig.truth())?;
    // The target protocol (calib's, for this sensor): views of a fine board tilted about axes
    // going round the optical axis, filling the image, planned for the camera (docs/calib.md).
    let protocol = calib::TargetProtocol {
        views,
        ..calib::TargetProtocol::for_sensor(truth.camera.width)
    };
    let board = hal_sim::Checkerboard {
        squares_x: protocol.board.squares_x,
        squares_y: protocol.board.squares_y,
        square_m: protocol.board.square_m,
        ..hal_sim::Checkerboard::default()
    };
    let mut frames = Vec::with_capacity(views);
    for pose in calib::plan_board_poses(&protocol, &truth.camera, seed.wrapping_add(100))? {
        let pose = hal_sim::TargetPose {
            rotation: pose.rotation,
            translation: pose.translation,
        };
        frames.push(rig.capture_checkerboard(&board, &pose, 0.5)?.frame);
    }
    let digitizer = calib::DigitizerProtocol::default();
    let mut dig = rig.digitizer(DIGITIZER_M, seed.wrapping_add(200));
    let tips = dig
        .tip_observations(digitizer.tips, digitizer.tip_depth_m, TIP_PIXEL_PX)
        .into_iter()
        .map(|o| TipCorrespondence {
            world: o.measured,
            pixel: o.pixel,
        })
        .collect();
    let angles = &digitizer.lamp_angles_deg;
    let lamp = dig
        .lamp_positions(angles)
        .into_iter()
        .zip(angles.iter())
        .map(|(p, &a)| LampReading {
            angle_deg: a,
            position: p,
        })
        .collect();
    let sphere_points = dig.sphere_surface(digitizer.sphere_points);
    let mut noise = rand_chacha::ChaCha8Rng::seed_from_u64(seed.wrapping_add(300));
    // Caliper reading: Gaussian noise by Box-Muller.
    let (u1, u2): (f64, f64) = (noise.gen_range(1e-12..1.0), noise.gen());
    let gauss = (-2.0 * u1.ln()).sqrt() * (std::f64::consts::TAU * u2).cos();
    let diameter = 2.0 * truth.sphere.radius + CALIPER_M * gauss;
    Ok((
        CalibrationInputs {
            board: protocol.board,
            target_frames: frames,
            tips,
            lamp,
            sphere_points,
            sphere_diameter_m: diameter,
        },
        truth,
    ))
}

/// Calibrates the simulated rig of `config`; returns the calibration run, its inputs and the truth.
pub fn calibrate_sim(
    config: hal_sim::SimConfig,
    views: usize,
    seed: u64,
) -> Result<(calib::CalibrationRun, CalibrationInputs, Calibration)> {
    let (inputs, truth) = simulated_inputs(config, views, seed)?;
    let run =
        calib::calibrate(&inputs, &CalibrationOptions::default()).context("calibration failed")?;
    Ok((run, inputs, truth))
}

/// `gantry calibrate`.
pub fn run(args: CalibrateArgs) -> Result<()> {
    if !args.sim {
        let rig = args
            .rig
            .as_ref()
            .context("--rig rig.toml is required without --sim")?;
        let cfg = gantry_hal::RigConfig::load(rig)?;
        let _devices = gantry_hal::open_real_rig(&cfg)?;
        bail!("calibration on real devices: devices opened, but target capture and digitizer import are not wired yet");
    }
    if !(args.scale > 0.0 && args.scale <= 1.0) {
        bail!("--scale must be in (0, 1], got {}", args.scale);
    }
    let config = hal_sim::SimConfig {
        seed: args.seed,
        ..hal_sim::SimConfig::with_scale(args.scale)
    };
    let (run, inputs, truth) = calibrate_sim(config, args.views, args.seed)?;
    std::fs::create_dir_all(&args.out)
        .with_context(|| format!("cannot create {}", args.out.display()))?;
    calib::io::write_run(&args.out, &inputs, &run, Some(&truth))?;
    let c = &run.calibration;
    let t = &truth;
    let dc = (c.camera.cx - t.camera.cx).hypot(c.camera.cy - t.camera.cy);
    let rot = calib::rotation_angle_between(&c.pose.rotation_matrix(), &t.pose.rotation_matrix());
    let dl =
        (nalgebra::Vector3::from(c.lamp.centre) - nalgebra::Vector3::from(t.lamp.centre)).norm();
    let ds = (nalgebra::Vector3::from(c.sphere.centre) - nalgebra::Vector3::from(t.sphere.centre))
        .norm();
    println!("wrote {}", args.out.join("calibration.json").display());
    println!("reprojection RMS: {:.4} px", run.reprojection_rms());
    println!(
        "against the simulator's truth: fx {:+.4}%, fy {:+.4}%, principal point {:.2} px, k1 {:+.2}%",
        100.0 * (c.camera.fx / t.camera.fx - 1.0),
        100.0 * (c.camera.fy / t.camera.fy - 1.0),
        dc,
        100.0 * (c.camera.k1 / t.camera.k1 - 1.0)
    );
    println!(
        "  rotation {:.4}°, translation {:.3} mm, lamp centre {:.3} mm, lamp radius {:.3} mm, sphere centre {:.3} mm",
        rot.to_degrees(),
        1e3 * (c.pose.translation_vector() - t.pose.translation_vector()).norm(),
        1e3 * dl,
        1e3 * (c.lamp.radius - t.lamp.radius).abs(),
        1e3 * ds
    );
    Ok(())
}
