//! Frame-consistency checks on series rendered by the simulator's sensor model with the lamp
//! output changed during the series.

mod common;

use common::glossy_rig;
use gantry_hal::{BayerFrame, BayerPattern};
use hdr::{check_frames, inconsistent_frames, merge, thesis_ladder, MergeOptions};

/// The thesis's series at lamp angle 90° with lamp output `scale(k)` during exposure `k`.
fn series(sim: &hal_sim::SimRig, scale: impl Fn(usize) -> f64) -> Vec<BayerFrame> {
    let scene = sim.scene();
    let lamp = scene.lamp_rate_e(90.0);
    let base = scene.stray_rate_e();
    let temp = sim.truth().sensor.temperature_c;
    thesis_ladder()
        .iter()
        .enumerate()
        .map(|(k, &t)| {
            let data = scene
                .expose(&lamp, scale(k), &base, t, temp, 1000 + k as u64)
                .unwrap();
            BayerFrame::new(
                scene.width(),
                scene.height(),
                10,
                BayerPattern::Rggb,
                data,
                t,
                0.0,
                temp,
                k as u64,
            )
            .unwrap()
        })
        .collect()
}

#[test]
fn clean_series_agree_and_lamp_faults_stand_out() {
    let sim = glossy_rig(0.12, 9, 10.0, 0.0);
    let opts = MergeOptions::default();
    let report = |name: &str, frames: &[BayerFrame]| {
        let img = merge(frames, None, &opts).unwrap();
        let checks = check_frames(frames, &img).unwrap();
        let ratios: Vec<String> = checks
            .iter()
            .map(|c| format!("{:.3}({})", c.ratio, c.pixels))
            .collect();
        println!("{name}: {}", ratios.join(" "));
        checks
    };
    let clean = report("clean", &series(&sim, |_| 1.0));
    for c in &clean {
        if c.pixels >= 200 {
            assert!((c.ratio - 1.0).abs() < 0.01, "{c:?}");
        }
    }
    assert!(clean.iter().filter(|c| c.pixels >= 200).count() >= 8);
    assert!(inconsistent_frames(&clean, 0.02, 200).is_empty());

    // The lamp drops out 40% into exposure 13 and stays off.
    let drop = report(
        "dropout",
        &series(&sim, |k| match k {
            0..=12 => 1.0,
            13 => 0.4,
            _ => 0.0,
        }),
    );
    // The spoiled fit makes neighbours deviate too: the series as a whole is flagged.
    let bad = inconsistent_frames(&drop, 0.02, 200);
    assert!(bad.contains(&13), "{bad:?}");

    // A 5% jump of the lamp output before exposure 10.
    let flick = report(
        "flicker",
        &series(&sim, |k| if k < 10 { 1.0 } else { 1.05 }),
    );
    let usable: Vec<&hdr::FrameCheck> = flick.iter().filter(|c| c.pixels >= 200).collect();
    let spread = usable.iter().map(|c| c.ratio).fold(f64::MIN, f64::max)
        - usable.iter().map(|c| c.ratio).fold(f64::MAX, f64::min);
    println!("flicker spread {spread:.4}");
    assert!(spread > 0.03, "{spread}");
    assert!(!inconsistent_frames(&flick, 0.02, 200).is_empty());
}

#[test]
fn a_lamp_change_spoils_the_fit_of_many_pixels() {
    let sim = glossy_rig(0.12, 9, 10.0, 0.0);
    let opts = MergeOptions::default();
    let all = sim.scene().width() * sim.scene().height();
    let quality = |frames: &[BayerFrame]| {
        let img = merge(frames, None, &opts).unwrap();
        hdr::fit_quality(&img, 0..all, 5)
    };
    let clean = quality(&series(&sim, |_| 1.0));
    let dropout = quality(&series(&sim, |k| if k < 13 { 1.0 } else { 0.0 }));
    let flicker = quality(&series(&sim, |k| if k < 10 { 1.0 } else { 1.05 }));
    println!("low-correlation share: clean {clean:?}, dropout {dropout:?}, flicker {flicker:?}");
    assert!(clean.fitted > 1000, "{clean:?}");
    assert!(clean.low_fraction() < 0.01, "{clean:?}");
    assert!(dropout.low_fraction() > 0.03, "{dropout:?}");
    // A 5 % step keeps every pixel's values nearly on a line: this measure does not see it,
    // the per-frame ratios of `check_frames` do (test above).
    assert!(flicker.low_fraction() < 0.03, "{flicker:?}");
    // Indices outside the image are ignored; an empty region has no bad fits.
    let img = merge(&series(&sim, |_| 1.0), None, &opts).unwrap();
    assert_eq!(hdr::fit_quality(&img, [all, all + 7], 5).fitted, 0);
    assert_eq!(hdr::fit_quality(&img, [], 5).low_fraction(), 0.0);
}
