//! `gantry calibrate`: geometric calibration of camera, lamp circle and sphere (thesis §3.2),
//! and `gantry calibrate intrinsics`: a camera from a folder of checkerboard photographs.
//! Argument parsing and composition only; the procedures are `calib`'s.
//!
//! On the simulated rig the inputs are produced the way an operator would (`calib::sim`): flat
//! frames of a diffuser, checkerboard images in varied poses (several exposures of each, summed),
//! about 30 digitizer tip / pixel correspondences, about 30 digitized lamp positions, about 30
//! digitized points on the sphere and a caliper diameter, all with noise.

use anyhow::{bail, Context, Result};
use calib::{CalibrationInputs, CalibrationOptions};
use clap::Args;
use gantry_hal::{BayerFrame, BayerPattern};
use std::path::{Path, PathBuf};
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
#[command(args_conflicts_with_subcommands = true, subcommand_negates_reqs = true)]
pub struct CalibrateArgs {
    /// Camera intrinsics alone, from photographs.
    #[command(subcommand)]
    pub command: Option<CalibrateCommand>,
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
    /// Bits kept of the 16-bit PNG samples of `--from` (left-aligned, as `calibrate` writes
    /// them; 16 keeps the stacked frames' extra bits).
    #[arg(long, default_value_t = 16)]
    pub bit_depth: u8,
    /// Bayer pattern of the target images (`--from`).
    #[arg(long, value_enum, default_value = "rggb")]
    pub pattern: PatternArg,
    /// Exposure of the target images captured with `--rig`, seconds.
    #[arg(long, default_value_t = 0.05)]
    pub exposure_s: f64,
    /// Output directory.
    #[arg(long)]
    pub out: Option<PathBuf>,
    /// Sensor scale of the simulated camera.
    #[arg(long, default_value_t = 1.0)]
    pub scale: f64,
    /// Number of checkerboard poses (the target protocol's default: 30).
    #[arg(long, default_value_t = 30)]
    pub views: usize,
    /// Exposures of each pose, summed into its target image (`--sim`, `--rig`).
    #[arg(long, default_value_t = 4)]
    pub frames_per_view: usize,
    /// Exposures of a uniformly lit diffuser for the flat-field correction (`--sim`, `--rig`;
    /// 0: none). `--from` uses DIR/flats/*.png when present.
    #[arg(long, default_value_t = 16)]
    pub flat_frames: usize,
    /// Seed of the simulator and of the measurement noise.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
}

/// Subcommands of `gantry calibrate`.
#[derive(clap::Subcommand, Debug)]
pub enum CalibrateCommand {
    /// Calibrate a camera from checkerboard photographs (PNG, JPEG, TIFF) alone, without the
    /// digitizer or the rig.
    Intrinsics(calib::IntrinsicsJob),
}

/// The target protocol of this sensor width with the command line's numbers.
fn target_protocol(args: &CalibrateArgs, width: usize) -> calib::TargetProtocol {
    calib::TargetProtocol {
        views: args.views,
        frames_per_view: args.frames_per_view,
        flat_frames: args.flat_frames,
        ..calib::TargetProtocol::for_sensor(width)
    }
}

/// The checkerboard of `--board`/`--square-mm`, or the protocol's board for this sensor width.
fn board_of(args: &CalibrateArgs, width: usize) -> Result<calib::BoardGeometry> {
    let default = calib::TargetProtocol::for_sensor(width).board;
    let (squares_x, squares_y) = match &args.board {
        Some(text) => calib::parse_grid(text).context("--board takes COLSxROWS squares")?,
        None => (default.squares_x, default.squares_y),
    };
    let board = calib::BoardGeometry {
        squares_x,
        squares_y,
        square_m: args.square_mm.map_or(default.square_m, |mm| mm * 1e-3),
    };
    board.validate()?;
    Ok(board)
}

/// Calibrates `inputs` and writes `out/calibration.json`.
fn calibrate_files(inputs: &CalibrationInputs, out: &Path) -> Result<()> {
    let run =
        calib::calibrate(inputs, &CalibrationOptions::default()).context("calibration failed")?;
    std::fs::create_dir_all(out).with_context(|| format!("cannot create {}", out.display()))?;
    let path = out.join("calibration.json");
    run.calibration.write(&path)?;
    println!("wrote {}", path.display());
    println!("reprojection RMS: {:.4} px", run.reprojection_rms());
    Ok(())
}

/// Waits for the operator to press Enter after `prompt`.
fn wait_for_operator(prompt: &str) -> Result<()> {
    eprintln!("{prompt}, then press Enter");
    let mut line = String::new();
    if std::io::stdin().read_line(&mut line)? == 0 {
        bail!("standard input closed while waiting for: {prompt}");
    }
    Ok(())
}

/// Writes `frames` as `dir/{stem}_NN.png`.
fn write_pngs(dir: &Path, stem: &str, frames: &[BayerFrame]) -> Result<()> {
    std::fs::create_dir_all(dir).with_context(|| format!("cannot create {}", dir.display()))?;
    for (i, f) in frames.iter().enumerate() {
        calib::write_atomic(
            &dir.join(format!("{stem}_{i:02}.png")),
            &calib::frame_png16(f)?,
        )?;
    }
    Ok(())
}

/// Target images and flat frames from the rig's camera. The operator first holds the diffuser
/// in front of the lens (flat frames, checked at once), then shows the board in a new pose and
/// presses Enter before each one; every pose is exposed `--frames-per-view` times, the
/// exposures summed, and the pose taken again if the board is not found in it.
fn capture_targets(
    args: &CalibrateArgs,
    rig_path: &Path,
) -> Result<(Vec<BayerFrame>, Vec<BayerFrame>)> {
    let cfg = gantry_hal::RigConfig::load(rig_path)?;
    let mut rig = match cfg.backend {
        gantry_hal::Backend::Real => gantry_hal::open_real_rig(&cfg)
            .with_context(|| format!("cannot open the devices of {}", rig_path.display()))?,
        gantry_hal::Backend::Sim => hal_sim::SimRig::from_rig_config(&cfg)?.rig(),
    };
    if args.frames_per_view == 0 {
        bail!("--frames-per-view must be at least 1");
    }
    rig.camera.set_exposure(args.exposure_s)?;
    let mut capture = |n: usize| -> Result<Vec<BayerFrame>> {
        (0..n)
            .map(|_| {
                let f = rig.camera.capture(Duration::from_secs(60))?;
                f.validate()?;
                Ok(f)
            })
            .collect()
    };
    let mut flats = Vec::new();
    let mut flat = None;
    if args.flat_frames > 0 {
        wait_for_operator(
            "flat field: hold the evenly lit diffuser (opal glass) against the lens, the image bright but not saturated",
        )?;
        flats = capture(args.flat_frames)?;
        write_pngs(&out_dir(args)?.join("flats"), "flat", &flats)?;
        // Checked at once, so that the operator can fix the light before showing the board.
        flat = Some(calib::FlatField::estimate(&flats).context(
            "the flat frames cannot measure the sensor (adjust the diffuser's light or --exposure-s)",
        )?);
    }
    let mut frames = Vec::with_capacity(args.views);
    let mut board = None;
    for k in 0..args.views {
        let mut prompt = format!(
            "target {}/{}: hold the checkerboard still in a new pose (tilted, filling the image)",
            k + 1,
            args.views
        );
        // Every pose is checked at once: a pose whose board is not found is taken again.
        loop {
            wait_for_operator(&prompt)?;
            let stack = calib::stack_frames(&capture(args.frames_per_view)?)?;
            let geometry = match board {
                Some(b) => b,
                None => *board.insert(board_of(args, stack.width)?),
            };
            let options = calib::CornerOptions::default();
            match calib::detect_board_flat(&stack, flat.as_ref(), &geometry, &options, k) {
                Ok(_) => {
                    frames.push(stack);
                    break;
                }
                Err(e) => {
                    eprintln!("{e}");
                    prompt = format!(
                        "target {}/{} again: the whole board must be in the image, sharp and not saturated",
                        k + 1,
                        args.views
                    );
                }
            }
        }
    }
    write_pngs(&out_dir(args)?.join("targets"), "target", &frames)?;
    Ok((frames, flats))
}

fn out_dir(args: &CalibrateArgs) -> Result<&Path> {
    args.out.as_deref().context("--out DIR is required")
}

/// `gantry calibrate`.
pub fn run(args: CalibrateArgs) -> Result<()> {
    if let Some(CalibrateCommand::Intrinsics(job)) = &args.command {
        print!("{}", job.run().context("calibration failed")?);
        println!();
        return Ok(());
    }
    let out = out_dir(&args)?;
    if let Some(dir) = &args.from {
        // The operator's files: target images and the digitizer log (as `--sim` writes them).
        let width = calib::read_frames_dir(
            &dir.join("targets"),
            "target images",
            false,
            args.bit_depth,
            args.pattern.into(),
        )?
        .first()
        .map_or(0, |f| f.width);
        let inputs = calib::read_session(
            dir,
            board_of(&args, width)?,
            args.digitizer.as_deref(),
            args.bit_depth,
            args.pattern.into(),
        )?;
        return calibrate_files(&inputs, out);
    }
    if !args.sim {
        let rig = args
            .rig
            .as_ref()
            .context("--rig rig.toml is required without --sim or --from")?;
        let digitizer = args.digitizer.clone().context(
            "with --rig pass --digitizer FILE.csv (tips, lamp and sphere points, caliper)",
        )?;
        // The log is read first: a missing or malformed file stops the session before the
        // operator spends time on the camera.
        let log = calib::read_digitizer_csv(&digitizer)?;
        let (frames, flats) = capture_targets(&args, rig)?;
        let width = frames.first().map_or(0, |f| f.width);
        let inputs = calib::inputs_from(board_of(&args, width)?, frames, flats, log);
        return calibrate_files(&inputs, out);
    }
    if !(args.scale > 0.0 && args.scale <= 1.0) {
        bail!("--scale must be in (0, 1], got {}", args.scale);
    }
    let config = hal_sim::SimConfig {
        seed: args.seed,
        ..hal_sim::SimConfig::with_scale(args.scale)
    };
    let (run, session) =
        calib::calibrate_rig_session(config, |width| target_protocol(&args, width), args.seed)
            .context("calibration of the simulated rig failed")?;
    let truth = session.truth;
    std::fs::create_dir_all(out).with_context(|| format!("cannot create {}", out.display()))?;
    calib::write_run(out, &session.inputs, &run, Some(&truth))?;
    println!("wrote {}", out.join("calibration.json").display());
    println!("reprojection RMS: {:.4} px", run.reprojection_rms());
    println!("{}", calib::TruthComparison::new(&run.calibration, &truth));
    Ok(())
}
