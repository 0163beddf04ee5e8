//! `gantry calibrate`: geometric calibration of camera, lamp circle and sphere (seed §3.2).
//!
//! On the simulated rig the inputs are produced the way an operator would: checkerboard images
//! in varied poses, about 30 digitizer tip / pixel correspondences, about 30 digitized lamp
//! positions, about 30 digitized points on the sphere and a caliper diameter, all with noise.

use anyhow::{bail, Context, Result};
use calib::{Calibration, CalibrationInputs, CalibrationOptions, LampReading, TipCorrespondence};
use clap::Args;
use gantry_hal::{BayerFrame, BayerPattern};
use rand::{Rng, SeedableRng};
use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::time::Duration;

/// Bayer pattern on the command line.
#[derive(clap::ValueEnum, Clone, Copy, Debug)]
pub enum PatternArg {
    /// R G / G B.
    Rggb,
    /// B G / G R.
    Bggr,
    /// G R / B G.
    Grbg,
    /// G B / R G.
    Gbrg,
}

impl From<PatternArg> for BayerPattern {
    fn from(p: PatternArg) -> Self {
        match p {
            PatternArg::Rggb => BayerPattern::Rggb,
            PatternArg::Bggr => BayerPattern::Bggr,
            PatternArg::Grbg => BayerPattern::Grbg,
            PatternArg::Gbrg => BayerPattern::Gbrg,
        }
    }
}

/// Arguments of `gantry calibrate`.
#[derive(Args, Debug)]
pub struct CalibrateArgs {
    /// Calibrate the simulated rig (and write its truth beside the result).
    #[arg(long, required_unless_present_any = ["rig", "from"], conflicts_with_all = ["rig", "from"])]
    pub sim: bool,
    /// Calibrate real devices described by this rig configuration.
    #[arg(long)]
    pub rig: Option<PathBuf>,
    /// Calibrate from files an operator collected: DIR/targets/*.png (16-bit target images) and
    /// DIR/digitizer.csv (the layout `--sim` writes).
    #[arg(long, conflicts_with = "rig")]
    pub from: Option<PathBuf>,
    /// Digitizer log (CSV) for `--rig`, or instead of DIR/digitizer.csv for `--from`.
    #[arg(long)]
    pub digitizer: Option<PathBuf>,
    /// Checkerboard squares COLSxROWS for `--from`/`--rig` (default: the protocol's board).
    #[arg(long)]
    pub board: Option<String>,
    /// Checkerboard square side in millimetres for `--from`/`--rig`.
    #[arg(long)]
    pub square_mm: Option<f64>,
    /// Bits per sample of the target images (`--from`).
    #[arg(long, default_value_t = 10)]
    pub bit_depth: u8,
    /// Bayer pattern of the target images (`--from`).
    #[arg(long, value_enum, default_value = "rggb")]
    pub pattern: PatternArg,
    /// Exposure of the target images captured with `--rig`, seconds.
    #[arg(long, default_value_t = 0.05)]
    pub exposure_s: f64,
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

/// The checkerboard of `--board`/`--square-mm`, or the protocol's board for this sensor width.
fn board_of(args: &CalibrateArgs, width: usize) -> Result<calib::BoardGeometry> {
    let default = calib::TargetProtocol::for_sensor(width).board;
    let (sx, sy) = match &args.board {
        Some(text) => {
            let (a, b) = text
                .split_once(['x', 'X'])
                .context("--board takes COLSxROWS squares, e.g. 25x19")?;
            (
                a.trim().parse::<usize>().context("--board columns")?,
                b.trim().parse::<usize>().context("--board rows")?,
            )
        }
        None => (default.squares_x, default.squares_y),
    };
    let square_m = args.square_mm.map_or(default.square_m, |mm| mm * 1e-3);
    if sx < 3 || sy < 3 || !(square_m > 0.0 && square_m.is_finite()) {
        bail!("checkerboard {sx}x{sy} squares of {square_m} m: need at least 3x3 squares of positive size");
    }
    Ok(calib::BoardGeometry {
        squares_x: sx,
        squares_y: sy,
        square_m,
    })
}

/// Target images `targets/*.png` (16-bit, sorted by name) of a directory.
fn read_targets(dir: &Path, bit_depth: u8, pattern: BayerPattern) -> Result<Vec<BayerFrame>> {
    let targets = dir.join("targets");
    let mut paths: Vec<PathBuf> = std::fs::read_dir(&targets)
        .with_context(|| format!("cannot list {}", targets.display()))?
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| p.extension().is_some_and(|e| e.eq_ignore_ascii_case("png")))
        .collect();
    paths.sort();
    if paths.is_empty() {
        bail!("{}: no target images (*.png)", targets.display());
    }
    paths
        .iter()
        .map(|p| {
            calib::io::read_frame_png16(p, bit_depth, pattern)
                .with_context(|| format!("cannot read target image {}", p.display()))
        })
        .collect()
}

/// Calibrates from an operator's files and writes `out/calibration.json`.
fn calibrate_files(
    args: &CalibrateArgs,
    frames: Vec<BayerFrame>,
    digitizer: &Path,
    out: &Path,
) -> Result<()> {
    let log = calib::io::read_digitizer_csv(digitizer)
        .with_context(|| format!("cannot read {}", digitizer.display()))?;
    let width = frames.first().map_or(0, |f| f.width);
    let inputs = CalibrationInputs {
        board: board_of(args, width)?,
        target_frames: frames,
        tips: log.tips,
        lamp: log.lamp,
        sphere_points: log.sphere_points,
        sphere_diameter_m: log.sphere_diameter_m,
    };
    let run =
        calib::calibrate(&inputs, &CalibrationOptions::default()).context("calibration failed")?;
    std::fs::create_dir_all(out).with_context(|| format!("cannot create {}", out.display()))?;
    let path = out.join("calibration.json");
    run.calibration.write(&path)?;
    println!("wrote {}", path.display());
    println!("reprojection RMS: {:.4} px", run.reprojection_rms());
    Ok(())
}

/// Target images from the rig's camera: the operator shows the board in a new pose and presses
/// Enter before each one.
fn capture_targets(args: &CalibrateArgs, rig_path: &Path) -> Result<Vec<BayerFrame>> {
    let cfg = gantry_hal::RigConfig::load(rig_path)?;
    let mut rig = match cfg.backend {
        gantry_hal::Backend::Real => gantry_hal::open_real_rig(&cfg)
            .with_context(|| format!("cannot open the devices of {}", rig_path.display()))?,
        gantry_hal::Backend::Sim => hal_sim::SimRig::from_rig_config(&cfg)?.rig(),
    };
    rig.camera.set_exposure(args.exposure_s)?;
    let stdin = std::io::stdin();
    let mut frames = Vec::with_capacity(args.views);
    for k in 0..args.views {
        eprintln!(
            "target {}/{}: hold the checkerboard in a new pose (tilted, filling the image), then press Enter",
            k + 1,
            args.views
        );
        let mut line = String::new();
        if stdin.read_line(&mut line)? == 0 {
            bail!(
                "standard input closed after {k} of {} target images",
                args.views
            );
        }
        let f = rig.camera.capture(Duration::from_secs(60))?;
        f.validate()?;
        frames.push(f);
    }
    let dir = args.out.join("targets");
    std::fs::create_dir_all(&dir).with_context(|| format!("cannot create {}", dir.display()))?;
    for (i, f) in frames.iter().enumerate() {
        calib::io::write_atomic(
            &dir.join(format!("target_{i:02}.png")),
            &calib::io::frame_png16(f)?,
        )?;
    }
    Ok(frames)
}

/// `gantry calibrate`.
pub fn run(args: CalibrateArgs) -> Result<()> {
    if let Some(dir) = &args.from {
        // The operator's files: target images and the digitizer log (as `--sim` writes them).
        let frames = read_targets(dir, args.bit_depth, args.pattern.into())?;
        let digitizer = args
            .digitizer
            .clone()
            .unwrap_or_else(|| dir.join("digitizer.csv"));
        return calibrate_files(&args, frames, &digitizer, &args.out);
    }
    if !args.sim {
        let rig = args
            .rig
            .as_ref()
            .context("--rig rig.toml is required without --sim or --from")?;
        let digitizer = args.digitizer.clone().context(
            "with --rig pass --digitizer FILE.csv (tips, lamp and sphere points, caliper)",
        )?;
        let frames = capture_targets(&args, rig)?;
        return calibrate_files(&args, frames, &digitizer, &args.out);
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
