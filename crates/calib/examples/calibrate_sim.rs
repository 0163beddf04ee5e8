//! Calibrates the simulated rig (hal-sim) at the default noise and prints every error figure of
//! the calibration goals against the simulator's ground truth. The targets follow calib's
//! default protocol for the sensor ([`calib::TargetProtocol::for_sensor`]).
//!
//! `cargo run --release -p calib --example calibrate_sim -- [scale] [views] [seed] [--estimate-k2]
//!  [--frames-per-view F] [--flat-frames M] [--defocus SIGMA_PX] [--out DIR]`

#[path = "../tests/common/mod.rs"]
mod common;

use calib::TargetProtocol;
use calib::{calibrate, CalibrationOptions};
use common::{corner_error, errors, simulate_config, SimNoise};
use std::time::Instant;

fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    const WITH_VALUE: [&str; 4] = ["--out", "--frames-per-view", "--flat-frames", "--defocus"];
    let value = |name: &str| {
        args.iter()
            .position(|a| a == name)
            .and_then(|i| args.get(i + 1))
    };
    let positional: Vec<&String> = args
        .iter()
        .enumerate()
        .filter(|(i, a)| {
            !a.starts_with("--") && (*i == 0 || !WITH_VALUE.contains(&args[i - 1].as_str()))
        })
        .map(|(_, a)| a)
        .collect();
    let defaults = calib::TargetProtocol::default();
    let frames_per_view: usize =
        value("--frames-per-view").map_or(defaults.frames_per_view, |v| v.parse().expect("F"));
    let flat_frames: usize =
        value("--flat-frames").map_or(defaults.flat_frames, |v| v.parse().expect("M"));
    let scale: f64 = positional
        .first()
        .map_or(1.0, |s| s.parse().expect("scale"));
    let views: usize = positional
        .get(1)
        .map_or(calib::TargetProtocol::default().views, |s| {
            s.parse().expect("views")
        });
    let seed: u64 = positional.get(2).map_or(1, |s| s.parse().expect("seed"));
    let out = value("--out");
    let mut opts = CalibrationOptions::default();
    if args.iter().any(|a| a == "--estimate-k2") {
        opts.intrinsics.model = calib::DistortionModel::K1K2;
    }
    opts.min_views = views.min(10);
    let t0 = Instant::now();
    let mut cfg = hal_sim::SimConfig {
        seed,
        ..hal_sim::SimConfig::with_scale(scale)
    };
    if let Some(d) = value("--defocus") {
        cfg.sensor.defocus_sigma_px = d.parse().expect("--defocus SIGMA_PX");
    }
    let defocus = cfg.sensor.defocus_sigma_px;
    let sim = simulate_config(cfg, seed, SimNoise::default(), None, |w| TargetProtocol {
        views,
        frames_per_view,
        flat_frames,
        ..TargetProtocol::for_sensor(w)
    });
    let t_sim = t0.elapsed().as_secs_f64();
    let t1 = Instant::now();
    let run = calibrate(&sim.inputs, &opts).expect("calibration");
    let t_cal = t1.elapsed().as_secs_f64();
    let cam = &sim.truth.camera;
    println!(
        "scale {scale} ({}x{}), {views} target images ({frames_per_view} exposures each, {flat_frames} flat frames) of a {}x{} board of {} mm squares, seed {seed}, defocus {defocus} px, estimate_k2 {}",
        cam.width,
        cam.height,
        sim.inputs.board.squares_x,
        sim.inputs.board.squares_y,
        sim.inputs.board.square_m * 1e3,
        opts.intrinsics.model != calib::DistortionModel::K1
    );
    println!("simulation {t_sim:.1} s, calibration {t_cal:.1} s");
    let mut all = Vec::new();
    for (d, t) in run.corners.iter().zip(&sim.true_corners) {
        if let Some(d) = d {
            all.push(corner_error(d, t));
        }
    }
    let rms = (all.iter().map(|e| e.0 * e.0).sum::<f64>() / all.len().max(1) as f64).sqrt();
    let max = all.iter().map(|e| e.1).fold(0.0, f64::max);
    println!(
        "corners: found in {}/{} images, error vs truth rms {rms:.4} px, max {max:.4} px",
        all.len(),
        run.corners.len()
    );
    let e = errors(&run.calibration, &sim.truth);
    let c = &run.calibration.camera;
    println!(
        "reprojection RMS (checkerboard) {:.4} px",
        run.intrinsics.rms_px
    );
    println!(
        "extrinsic reprojection RMS (tips) {:.4} px",
        run.extrinsics.rms_px
    );
    println!(
        "closed form: fx {:.2} fy {:.2} cx {:.2} cy {:.2}",
        run.intrinsics.initial.fx,
        run.intrinsics.initial.fy,
        run.intrinsics.initial.cx,
        run.intrinsics.initial.cy
    );
    println!(
        "fx {:.3} (true {:.3}) error {:.4} %   [tolerance 0.2 %]",
        c.fx,
        cam.fx,
        100.0 * e.fx_rel
    );
    println!(
        "fy {:.3} (true {:.3}) error {:.4} %   [tolerance 0.2 %]",
        c.fy,
        cam.fy,
        100.0 * e.fy_rel
    );
    println!(
        "principal point ({:.3}, {:.3}) (true ({:.3}, {:.3})) error {:.4} px   [tolerance 1 px]",
        c.cx, c.cy, cam.cx, cam.cy, e.principal_px
    );
    println!(
        "k1 {:.5} (true {:.5}) error {:.3} %   [tolerance 5 %]",
        c.k1,
        cam.k1,
        100.0 * e.k1_rel
    );
    println!("k2 {:.4} (true {:.4})", c.k2, cam.k2);
    println!(
        "extrinsic rotation error {:.5} deg   [tolerance 0.05 deg]",
        e.rotation_deg
    );
    println!(
        "extrinsic translation error |t - t_true| {:.4} mm   [tolerance 0.5 mm]; camera centre error {:.4} mm",
        e.translation_mm, e.camera_centre_mm
    );
    println!(
        "lamp circle centre error {:.4} mm   [tolerance 0.5 mm]; radius error {:.4} mm   [tolerance 0.3 mm]",
        e.lamp_centre_mm, e.lamp_radius_mm
    );
    println!(
        "lamp normal error {:.4} deg, reference error {:.4} deg, rms {:.4} mm",
        e.lamp_normal_deg,
        e.lamp_reference_deg,
        run.lamp.rms_m * 1e3
    );
    println!(
        "sphere centre error {:.4} mm   [tolerance 0.1 mm]; rms {:.4} mm",
        e.sphere_centre_mm,
        run.sphere.rms_m * 1e3
    );
    println!(
        "pixel rays at the sphere: largest miss {:.4} mm; sphere projection: largest error {:.4} px",
        e.ray_at_sphere_mm, e.sphere_projection_px
    );
    if let Some(dir) = out {
        let written = calib::write_run(
            std::path::Path::new(dir),
            &sim.inputs,
            &run,
            Some(&sim.truth),
        )
        .expect("write");
        println!("wrote {} files into {dir}", written.len());
    }
}
