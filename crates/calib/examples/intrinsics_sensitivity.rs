//! How well can the intrinsic fit do on this geometry? Fits the simulator's true corner pixels
//! plus Gaussian noise of the given sigma (no image processing involved).
//!
//! `cargo run --release -p calib --example intrinsics_sensitivity -- [scale] [views] [sigma_px] [max_tilt_rad] [max_offset_m] [--fix-k2]`

#[path = "../tests/common/mod.rs"]
mod common;

use calib::{fit_intrinsics, IntrinsicOptions};
use rand::SeedableRng;
use rand_distr::{Distribution, Normal};

fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let positional: Vec<&String> = args.iter().filter(|a| !a.starts_with("--")).collect();
    let scale: f64 = positional
        .first()
        .map_or(0.25, |s| s.parse().expect("scale"));
    let views: usize = positional.get(1).map_or(12, |s| s.parse().expect("views"));
    let sigma: f64 = positional.get(2).map_or(0.0, |s| s.parse().expect("sigma"));
    let fix_k2 = args.iter().any(|a| a == "--fix-k2");
    let tilt: f64 = positional.get(3).map_or(0.9, |s| s.parse().expect("tilt"));
    let offset: f64 = positional
        .get(4)
        .map_or(0.012, |s| s.parse().expect("offset"));
    let sim = common::simulate_with(
        scale,
        views,
        1,
        common::SimNoise::default(),
        common::PoseSpread {
            max_tilt_rad: tilt,
            max_offset_m: offset,
        },
    );
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(5);
    let n = Normal::new(0.0, sigma.max(1e-300)).unwrap();
    let noisy: Vec<Vec<[f64; 2]>> = sim
        .true_corners
        .iter()
        .map(|v| {
            v.iter()
                .map(|p| [p[0] + n.sample(&mut rng), p[1] + n.sample(&mut rng)])
                .collect()
        })
        .collect();
    let cam = sim.truth.camera;
    let fit = fit_intrinsics(
        &sim.inputs.board,
        &noisy,
        cam.width,
        cam.height,
        &IntrinsicOptions {
            estimate_k2: !fix_k2,
        },
    )
    .expect("fit");
    let c = fit.camera;
    println!(
        "scale {scale} views {views} sigma {sigma} px fix_k2 {fix_k2} tilt {tilt} offset {offset}: rms {:.4} px",
        fit.rms_px
    );
    println!(
        "fx err {:.4} %, fy err {:.4} %, pp err ({:.3}, {:.3}) px, k1 {:.4} (true {}), k2 {:.3}",
        100.0 * (c.fx / cam.fx - 1.0),
        100.0 * (c.fy / cam.fy - 1.0),
        c.cx - cam.cx,
        c.cy - cam.cy,
        c.k1,
        cam.k1,
        c.k2
    );
}
