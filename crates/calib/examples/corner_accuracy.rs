//! Accuracy of the corner detector against the simulator's true corner pixels, for one way of
//! taking and pre-processing the target images.
//!
//! `cargo run --release -p calib --example corner_accuracy -- [--scale S] [--views N] [--seed K]
//!  [--frames-per-view F] [--flat-frames M] [--image balanced|green] [--prnu SIGMA]
//!  [--defocus SIGMA_PX]`
//!
//! Defaults: full resolution, 6 views, seed 1, the target protocol's exposures and flat frames,
//! the detector's default image, the simulated sensor's own PRNU and blur.

#[path = "../tests/common/mod.rs"]
mod common;

use calib::{CornerImage, CornerOptions, TargetProtocol};

fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let get = |name: &str| {
        args.iter()
            .position(|a| a == name)
            .and_then(|i| args.get(i + 1))
            .map(String::as_str)
    };
    let num = |name: &str, default: f64| get(name).map_or(default, |v| v.parse().expect(name));
    let scale = num("--scale", 1.0);
    let seed = num("--seed", 1.0) as u64;
    let views = num("--views", 6.0) as usize;
    let defaults = TargetProtocol::default();
    let frames = num("--frames-per-view", defaults.frames_per_view as f64) as usize;
    let flats = num("--flat-frames", defaults.flat_frames as f64) as usize;
    let image = match get("--image") {
        None | Some("balanced") => CornerImage::Balanced,
        Some("green") => CornerImage::Green,
        Some(other) => panic!("--image balanced|green, not {other}"),
    };
    let mut cfg = hal_sim::SimConfig {
        seed,
        ..hal_sim::SimConfig::with_scale(scale)
    };
    if let Some(p) = get("--prnu") {
        cfg.sensor.prnu_sigma = p.parse().expect("--prnu");
    }
    if let Some(d) = get("--defocus") {
        cfg.sensor.defocus_sigma_px = d.parse().expect("--defocus");
    }
    let (prnu, defocus) = (cfg.sensor.prnu_sigma, cfg.sensor.defocus_sigma_px);
    let sim = common::simulate_config(cfg, seed, common::SimNoise::default(), None, |w| {
        TargetProtocol {
            views,
            frames_per_view: frames,
            flat_frames: flats,
            ..TargetProtocol::for_sensor(w)
        }
    });
    let opts = CornerOptions {
        image,
        ..CornerOptions::default()
    };
    let t0 = std::time::Instant::now();
    let errors = common::detected_corner_errors(&sim, &opts, true);
    let max = errors.iter().map(|e| e.1).fold(0.0, f64::max);
    println!(
        "scale {scale}, {views} views, seed {seed}, {frames} exposures per view, {flats} flat frames, {image:?} image, PRNU {prnu}, defocus {defocus} px: corner error rms {:.4} px, max {max:.4} px (detection {:.1} s)",
        common::pooled_rms(&errors),
        t0.elapsed().as_secs_f64()
    );
}
