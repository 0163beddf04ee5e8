//! Accuracy of the corner detector against the simulator's true corner pixels, for a few
//! detector settings.
//!
//! `cargo run --release -p calib --example corner_accuracy -- [scale] [views] [defocus_sigma_px]`

#[path = "../tests/common/mod.rs"]
mod common;

use calib::corners::SubpixelMethod;
use calib::{detect_board, CornerOptions};

fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let scale: f64 = args.first().map_or(0.25, |s| s.parse().expect("scale"));
    let views: usize = args.get(1).map_or(6, |s| s.parse().expect("views"));
    let sim = common::simulate(scale, views, 1, common::SimNoise::default());
    let skip_gradient = args.iter().any(|a| a == "--saddle-only");
    let mut settings = vec![];
    for (rs, wf) in [(1.0, 0.4), (1.5, 0.5)]
        .into_iter()
        .filter(|_| !skip_gradient)
    {
        settings.push(CornerOptions {
            refine_sigma_px: rs,
            window_fraction: wf,
            subpixel: SubpixelMethod::GradientOrthogonality,
            ..CornerOptions::default()
        });
    }
    for (ss, cap) in [
        (0.17, 100.0),
        (0.25, 100.0),
        (0.25, 12.0),
        (0.25, 8.0),
        (0.25, 5.0),
    ] {
        settings.push(CornerOptions {
            saddle_fraction: ss,
            max_saddle_sigma_px: cap,
            subpixel: SubpixelMethod::Saddle,
            ..CornerOptions::default()
        });
    }
    for opts in settings {
        let t0 = std::time::Instant::now();
        let (mut s2, mut n, mut bias2) = (0.0, 0usize, 0.0);
        let mut max: f64 = 0.0;
        for (i, (f, t)) in sim
            .inputs
            .target_frames
            .iter()
            .zip(&sim.true_corners)
            .enumerate()
        {
            let d = detect_board(f, &sim.inputs.board, &opts, i).expect("board");
            let fwd = common::corner_error(&d, t);
            let rev = t.iter().rev().cloned().collect::<Vec<_>>();
            let tt = if fwd.0 <= common::corner_error(&d, &rev).0 {
                t.clone()
            } else {
                rev
            };
            let (mut mx, mut my) = (0.0, 0.0);
            for (p, q) in d.iter().zip(&tt) {
                let (dx, dy) = (p[0] - q[0], p[1] - q[1]);
                mx += dx / d.len() as f64;
                my += dy / d.len() as f64;
                s2 += dx * dx + dy * dy;
                max = max.max(dx.hypot(dy));
                n += 1;
            }
            bias2 += mx * mx + my * my;
        }
        println!(
            "{:?} refine_sigma {} window {} saddle_fraction {} cap {} px: rms {:.4} px max {:.4} px, rms per-image mean offset {:.4} px",
            opts.subpixel,
            opts.refine_sigma_px,
            opts.window_fraction,
            opts.saddle_fraction,
            opts.max_saddle_sigma_px,
            (s2 / n as f64).sqrt(),
            max,
            (bias2 / views as f64).sqrt()
        );
        println!("  detection time {:.2} s", t0.elapsed().as_secs_f64());
    }
}
