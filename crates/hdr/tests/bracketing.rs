//! Adaptive bracketing on the simulated rig: a sweep of lamp positions captured with the full
//! 18-exposure ladder and with planned exposures, both compared with ground truth.

mod common;

use common::{glossy_rig, measurement_region, quantile, ready, T};
use hdr::{merge, plan_exposures, thesis_ladder, HdrImage, MergeOptions};

#[test]
fn planned_series_keep_coverage_and_accuracy_in_a_third_of_the_time() {
    let sim = glossy_rig(0.08, 3, 10.0, 2e-4);
    let mut rig = ready(&sim);
    let defects = common::dark_defects(&mut rig);
    let merge_opts = MergeOptions::default();
    let plan_opts = common::plan_options(&defects);
    let readout = sim.config().timing.readout_s;
    let ladder = thesis_ladder();
    let (mut time_full, mut time_adapt) = (0.0, 0.0);
    let (mut n_full, mut n_both) = (0usize, 0usize);
    let (mut err_full, mut err_adapt) = (Vec::new(), Vec::new());
    let mut previous: Option<HdrImage> = None;
    // 0.5° steps, as in a 330-position capture.
    for p in 0..30 {
        let angle = 60.0 + 0.5 * p as f64;
        rig.turntable.move_to(angle, T).unwrap();
        let roi = measurement_region(sim.truth(), angle, 80.0);
        let plan = plan_exposures(previous.as_ref(), Some(&roi), &plan_opts).unwrap();
        let shoot = |rig: &mut gantry_hal::Rig, ts: &[f64]| -> Vec<gantry_hal::BayerFrame> {
            ts.iter()
                .map(|&e| {
                    rig.camera.set_exposure(e).unwrap();
                    rig.camera.capture(T).unwrap()
                })
                .collect()
        };
        let c0 = sim.clock().seconds();
        let full = merge(&shoot(&mut rig, &ladder), Some(&defects), &merge_opts).unwrap();
        let c1 = sim.clock().seconds();
        let adapt = merge(
            &shoot(&mut rig, &plan.exposures_s),
            Some(&defects),
            &merge_opts,
        )
        .unwrap();
        let c2 = sim.clock().seconds();
        time_full += c1 - c0;
        time_adapt += c2 - c1;
        // The simulated camera is busy for exposure + readout per frame.
        let expected: f64 = plan.exposures_s.iter().map(|t| t + readout).sum();
        assert!((c2 - c1 - expected).abs() < 1e-6 * expected);
        let truth = sim.position_truth(angle);
        let a = common::agreement(&full, &adapt, &roi, &truth);
        n_full += a.full_valid;
        n_both += a.both_valid;
        err_full.extend(a.err_full);
        err_adapt.extend(a.err_adaptive);
        previous = Some(adapt);
    }
    let coverage = n_both as f64 / n_full as f64;
    let (mf, ma) = (quantile(&err_full, 0.5), quantile(&err_adapt, 0.5));
    println!(
        "camera time full {time_full:.1} s, adaptive {time_adapt:.1} s ({:.2}x); coverage \
         {coverage:.4} of {n_full}; median error full {:.3}%, adaptive {:.3}%",
        time_full / time_adapt,
        100.0 * mf,
        100.0 * ma
    );
    assert!(n_full > 2000, "{n_full}");
    assert!(time_adapt * 3.0 <= time_full);
    assert!(coverage >= 0.99, "{coverage}");
    assert!(ma <= mf + 0.01, "adaptive {ma} vs full {mf}");
}
