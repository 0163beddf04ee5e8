//! Adaptive bracketing against the thesis's full 18-exposure protocol on the simulated rig.
//!
//! `cargo run --release -p hdr --example adaptive_bracketing -- [scale] [positions] [lamp_gain]
//! [material spec]` (defaults 0.2, 24, 10, `phong:kd=0.2,ks=0.6,n=60`).
//!
//! The lamp sweeps `positions` angles from 10° to 165°. At every position the series is
//! captured twice through the simulated camera: with the full ladder, and with the exposures the
//! planner chose from the previous position's adaptive result. Both are merged and compared with
//! the simulator's noise-free signal rate. Two regions of interest are tried: every sphere pixel,
//! and the sphere pixels usable for BRDF measurement (incidence and view angles ≤ 80°, the
//! region recomputed for each lamp angle from the scene geometry). Printed per region: simulated
//! camera time (exposures + readout) of both protocols, the fraction of the region's pixels valid
//! with the full protocol that are also valid with the adaptive one, and the median relative
//! error of both against ground truth over the pixels valid in both.

#[path = "../tests/common/mod.rs"]
mod common;

use common::{measurement_region, ready, T};
use gantry_hal::{BayerFrame, Rig};
use hal_sim::SimRig;
use hdr::{merge, plan_exposures, thesis_ladder, HdrImage, MergeOptions};

fn median(v: &mut [f64]) -> f64 {
    if v.is_empty() {
        return f64::NAN;
    }
    v.sort_by(f64::total_cmp);
    v[v.len() / 2]
}

fn capture(rig: &mut Rig, sim: &SimRig, exposures: &[f64]) -> (Vec<BayerFrame>, f64) {
    let t0 = sim.clock().seconds();
    let frames = exposures
        .iter()
        .map(|&e| {
            rig.camera.set_exposure(e).unwrap();
            rig.camera.capture(T).unwrap()
        })
        .collect();
    (frames, sim.clock().seconds() - t0)
}

#[derive(Default)]
struct Totals {
    time_full: f64,
    time_adaptive: f64,
    full_valid: usize,
    both_valid: usize,
    err_full: Vec<f64>,
    err_adaptive: Vec<f64>,
    exposures: usize,
}

fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let scale: f64 = args.first().and_then(|s| s.parse().ok()).unwrap_or(0.2);
    let positions: usize = args.get(1).and_then(|s| s.parse().ok()).unwrap_or(24);
    let gain: f64 = args.get(2).and_then(|s| s.parse().ok()).unwrap_or(10.0);
    let spec = args
        .get(3)
        .cloned()
        .unwrap_or_else(|| common::GLOSSY.into());
    let sim = common::rig(common::config(scale, 1, gain), &spec);
    let mut rig = ready(&sim);
    let defects = common::dark_defects(&mut rig);
    let merge_opts = MergeOptions::default();
    let plan_opts = common::plan_options(&defects);
    let ladder = thesis_ladder();
    println!(
        "material {spec}, lamp x{gain}, scale {scale} ({}x{}), {positions} positions 10..165°",
        sim.truth().camera.width,
        sim.truth().camera.height
    );
    let angles: Vec<f64> = (0..positions)
        .map(|p| 10.0 + 155.0 * p as f64 / (positions.max(2) - 1) as f64)
        .collect();
    for region in ["sphere", "theta<=80"] {
        let mut tot = Totals::default();
        let mut previous: Option<HdrImage> = None;
        println!("\nregion of interest: {region}");
        println!(
            "  angle  full_s  adapt_s  n_exp  coverage  med_err_full%  med_err_adapt%  planned rates (DN/s)"
        );
        for (angle_index, &angle) in angles.iter().enumerate() {
            rig.turntable.move_to(angle, T).unwrap();
            let truth = sim.position_truth(angle);
            let roi: Vec<bool> = match region {
                "sphere" => truth.on_sphere.clone(),
                _ => measurement_region(sim.truth(), angle, 80.0),
            };
            let plan = plan_exposures(previous.as_ref(), Some(&roi), &plan_opts).unwrap();
            let (ff, t_full) = capture(&mut rig, &sim, &ladder);
            let (fa, t_adapt) = capture(&mut rig, &sim, &plan.exposures_s);
            let full = merge(&ff, Some(&defects), &merge_opts).unwrap();
            let adapt = merge(&fa, Some(&defects), &merge_opts).unwrap();
            let common::Agreement {
                full_valid: n_full,
                both_valid: n_both,
                err_full: mut ef,
                err_adaptive: mut ea,
            } = common::agreement(&full, &adapt, &roi, &truth);
            tot.time_full += t_full;
            tot.time_adaptive += t_adapt;
            tot.full_valid += n_full;
            tot.both_valid += n_both;
            tot.err_full.extend_from_slice(&ef);
            tot.err_adaptive.extend_from_slice(&ea);
            tot.exposures += plan.exposures_s.len();
            if positions > 40 && (angle_index % (positions / 20)) != 0 {
                previous = Some(adapt);
                continue;
            }
            println!(
                "  {angle:>5.1}  {t_full:>6.1}  {t_adapt:>7.2}  {:>5}  {:>8.4}  {:>13.3}  {:>14.3}  {}",
                plan.exposures_s.len(),
                n_both as f64 / n_full.max(1) as f64,
                100.0 * median(&mut ef),
                100.0 * median(&mut ea),
                plan.rate_range_dn_per_s
                    .map(|(a, b)| format!("{a:.3e}..{b:.3e}"))
                    .unwrap_or_else(|| "full ladder".into())
            );
            previous = Some(adapt);
        }
        let mf = median(&mut tot.err_full);
        let ma = median(&mut tot.err_adaptive);
        println!(
            "  TOTAL ({region}): camera time full {:.1} s, adaptive {:.1} s -> {:.2}x shorter; \
             mean {:.1} exposures/position; coverage {:.4}; median rel. error full {:.3}%, \
             adaptive {:.3}% (difference {:+.3} points)",
            tot.time_full,
            tot.time_adaptive,
            tot.time_full / tot.time_adaptive,
            tot.exposures as f64 / positions as f64,
            tot.both_valid as f64 / tot.full_valid.max(1) as f64,
            100.0 * mf,
            100.0 * ma,
            100.0 * (ma - mf)
        );
    }
}
