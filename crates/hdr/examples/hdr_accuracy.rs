//! HDR radiance accuracy of the thesis's 18-exposure protocol on the simulated rig, per decade of
//! true signal rate, for both offset models.
//!
//! `cargo run --release -p hdr --example hdr_accuracy -- [scale] [lamp_gain] [material spec]`
//! (defaults: 0.25, 10, `phong:kd=0.2,ks=0.6,n=60`). Prints, for lamp angles 30°, 90° and 150°,
//! the sphere pixels per decade, how many are valid, and the median / 90th-percentile relative
//! error against the simulator's noise-free signal rate.

#[path = "../tests/common/mod.rs"]
mod common;

use common::{capture_series, ready};
use hdr::{thesis_ladder, Intercept};

fn quantile(v: &mut [f64], q: f64) -> f64 {
    if v.is_empty() {
        return f64::NAN;
    }
    common::quantile(v, q)
}

fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let scale: f64 = args.first().and_then(|s| s.parse().ok()).unwrap_or(0.25);
    let gain: f64 = args.get(1).and_then(|s| s.parse().ok()).unwrap_or(10.0);
    let spec = args
        .get(2)
        .cloned()
        .unwrap_or_else(|| common::GLOSSY.into());
    let sim = common::rig(common::config(scale, 1, gain), &spec);
    let mut rig = ready(&sim);
    let defects = common::dark_defects(&mut rig);
    println!(
        "material {spec}, scale {scale}, lamp x{gain}; {} hot pixels (simulator: {}), dark median {} DN",
        defects.hot_count(),
        sim.hot_pixels().len(),
        defects.dark_median_dn()
    );
    let ladder = thesis_ladder();
    for angle in [30.0, 90.0, 150.0] {
        let frames = capture_series(&mut rig, angle, &ladder);
        let truth = sim.position_truth(angle);
        for intercept in [Intercept::Fitted, Intercept::BlackLevel(4.0)] {
            let img = common::merge_with(&frames, &defects, intercept);
            println!("angle {angle}°, {intercept:?}:");
            println!("  decade (DN/s)   sphere  valid   median%   p90%");
            let mut all = Vec::new();
            for d in -1..8 {
                let (mut n, mut rel) = (0, Vec::new());
                for i in 0..img.len() {
                    let t = truth.signal_rate_dn_per_s[i] as f64;
                    if !truth.on_sphere[i] || t.log10().floor() as i32 != d {
                        continue;
                    }
                    n += 1;
                    if img.valid[i] {
                        rel.push((img.radiance[i] as f64 - t).abs() / t);
                    }
                }
                if n == 0 {
                    continue;
                }
                all.extend_from_slice(&rel);
                let v = rel.len();
                println!(
                    "  1e{d:<2}..1e{:<2}     {n:>6} {v:>6}   {:>7.3} {:>7.3}",
                    d + 1,
                    100.0 * quantile(&mut rel, 0.5),
                    100.0 * quantile(&mut rel, 0.9)
                );
            }
            println!(
                "  all valid sphere pixels: {}  median {:.3}%  p90 {:.3}%",
                all.len(),
                100.0 * quantile(&mut all, 0.5),
                100.0 * quantile(&mut all, 0.9)
            );
        }
    }
}
