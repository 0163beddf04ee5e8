//! HDR radiance and hot pixels against the simulator's ground truth (`hal-sim`), with frames
//! captured through the `gantry-hal` camera trait of the simulated rig.

mod common;

use common::{capture_series, glossy_rig, quantile, ready};
use hdr::{merge, thesis_ladder, Intercept, MergeOptions};
use std::collections::HashSet;

/// Relative errors of the valid sphere pixels and their true rates.
fn errors(img: &hdr::HdrImage, truth: &hal_sim::PositionTruth) -> (Vec<f64>, Vec<f64>) {
    let mut rel = Vec::new();
    let mut rate = Vec::new();
    for i in 0..img.len() {
        if img.valid[i] && truth.on_sphere[i] {
            let t = truth.signal_rate_dn_per_s[i] as f64;
            rel.push((img.radiance[i] as f64 - t).abs() / t);
            rate.push(t);
        }
    }
    (rel, rate)
}

#[test]
fn radiance_matches_ground_truth_over_four_decades() {
    let sim = glossy_rig(0.2, 7, 10.0, 2e-4);
    let mut rig = ready(&sim);
    let defects = common::dark_defects(&mut rig);
    let angle = 150.0;
    let frames = capture_series(&mut rig, angle, &thesis_ladder());
    let truth = sim.position_truth(angle);
    for intercept in [Intercept::Fitted, Intercept::BlackLevel(4.0)] {
        let img = common::merge_with(&frames, &defects, intercept);
        let (rel, rate) = errors(&img, &truth);
        let med = quantile(&rel, 0.5);
        // Span of the valid rates without the extreme 0.2% at either end.
        let span = quantile(&rate, 0.998) / quantile(&rate, 0.002);
        println!(
            "{intercept:?}: {} valid sphere pixels, rates {:.3}..{:.3e} DN/s ({:.1} decades), \
             median rel. error {:.3}%, p90 {:.3}%",
            rel.len(),
            quantile(&rate, 0.0),
            quantile(&rate, 1.0),
            span.log10(),
            100.0 * med,
            100.0 * quantile(&rel, 0.9)
        );
        assert!(rel.len() > 5000, "{} valid sphere pixels", rel.len());
        assert!(span >= 1e4, "valid rates span only {span:.0}x");
        assert!(med <= 0.01, "median relative error {med}");
        // No decade of rates is badly off: the median of every populated decade is ≤ 2%.
        let lo = quantile(&rate, 0.0).log10().floor() as i32;
        for d in lo..lo + 8 {
            let sel: Vec<f64> = rel
                .iter()
                .zip(&rate)
                .filter(|(_, &r)| r.log10().floor() as i32 == d)
                .map(|(&e, _)| e)
                .collect();
            if sel.len() >= 20 {
                let m = quantile(&sel, 0.5);
                assert!(m <= 0.02, "decade 1e{d}: median {m} over {}", sel.len());
            }
        }
    }
}

#[test]
fn standard_errors_describe_the_actual_scatter() {
    let sim = glossy_rig(0.12, 21, 10.0, 0.0);
    let mut rig = ready(&sim);
    let angle = 60.0;
    let frames = capture_series(&mut rig, angle, &thesis_ladder());
    let truth = sim.position_truth(angle);
    let img = merge(&frames, None, &MergeOptions::default()).unwrap();
    let mut z = Vec::new();
    for i in 0..img.len() {
        // At least 3 residual degrees of freedom so that the scatter estimate itself is sound.
        if img.valid[i] && truth.on_sphere[i] && img.count[i] >= 5 {
            let t = truth.signal_rate_dn_per_s[i] as f64;
            z.push((img.radiance[i] as f64 - t) / img.std_error[i] as f64);
        }
    }
    let within = z.iter().filter(|v| v.abs() <= 2.0).count() as f64 / z.len() as f64;
    let med_abs = quantile(&z.iter().map(|v| v.abs()).collect::<Vec<_>>(), 0.5);
    println!(
        "{} pixels: {:.1}% within 2 standard errors, median |z| {med_abs:.3}",
        z.len(),
        100.0 * within
    );
    assert!(z.len() > 500, "{}", z.len());
    // Student t with 3..16 degrees of freedom: 86%..94% within ±2, median |t| 0.69..0.77.
    assert!((0.80..=0.98).contains(&within), "{within}");
    assert!((0.5..=1.0).contains(&med_abs), "{med_abs}");
}

#[test]
fn hot_pixels_match_the_simulator_list() {
    // A raised hot-pixel fraction gives a few hundred hot photosites at reduced resolution.
    let sim = glossy_rig(0.25, 5, 1.0, 5e-3);
    let mut rig = ready(&sim);
    let map = common::dark_defects(&mut rig);
    let truth: HashSet<(usize, usize)> = sim.hot_pixels().iter().copied().collect();
    let found: HashSet<(usize, usize)> = map.hot_pixels().into_iter().collect();
    let tp = truth.intersection(&found).count() as f64;
    let recall = tp / truth.len() as f64;
    let precision = tp / found.len() as f64;
    println!(
        "{} true hot pixels, {} found: recall {recall:.4}, precision {precision:.4}",
        truth.len(),
        found.len()
    );
    assert!(truth.len() > 200, "{}", truth.len());
    assert!(recall >= 0.99 && precision >= 0.99);
    // The black level of the simulated sensor (4 DN) is what the dark frame's median shows.
    assert_eq!(map.dark_median_dn(), sim.truth().sensor.black_level_dn);
}
