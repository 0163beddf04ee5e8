//! Frame pre-processing against the simulator's ground truth: the flat field measures the
//! sensor's photosite gains, and stacking plus flat-fielding make the corners more accurate.

mod common;

use calib::{CornerImage, CornerOptions, FlatField, TargetProtocol};
use hal_sim::{SimConfig, SimRig};
use std::sync::Arc;

#[test]
fn flat_field_from_simulated_flats_matches_the_photosite_gains() {
    let cfg = SimConfig {
        seed: 5,
        ..SimConfig::with_scale(0.25)
    };
    let rig = SimRig::new(cfg, Arc::new(brdf::analytic::Lambert { kd: [0.5; 3] })).unwrap();
    let flats = rig.capture_flat_frames(1.27, 0.5, 16).unwrap();
    let ff = FlatField::estimate(&flats).unwrap();
    let truth = rig.scene().prnu();
    let (w, h) = (ff.width, ff.height);
    // Away from the border, where the neighbourhood is whole: the estimate against the true
    // gains, and the spread of the true gains themselves (what no correction leaves).
    let (mut err2, mut spread2, mut n) = (0.0, 0.0, 0.0);
    for y in 20..h - 20 {
        for x in 20..w - 20 {
            let t = truth[y * w + x] as f64;
            err2 += (ff.gain[y * w + x] as f64 - t).powi(2);
            spread2 += (t - 1.0).powi(2);
            n += 1.0;
        }
    }
    let (err, spread) = ((err2 / n).sqrt(), (spread2 / n).sqrt());
    println!("flat-field gain error rms {err:.5}, true gain spread rms {spread:.5}");
    assert!(spread > 0.005, "the simulated sensor has a gain spread");
    assert!(err < 0.35 * spread, "error {err}, spread {spread}");
}

#[test]
fn stacking_and_flat_fielding_reduce_the_corner_error() {
    // The same three board poses, once as single exposures without a flat field found in the
    // green channel, once as the protocol takes them (4 exposures each, 16 flat frames, all
    // photosites colour-balanced).
    let single = |w: usize| TargetProtocol {
        views: 3,
        frames_per_view: 1,
        flat_frames: 0,
        ..TargetProtocol::for_sensor(w)
    };
    let default = |w: usize| TargetProtocol {
        views: 3,
        ..TargetProtocol::for_sensor(w)
    };
    let noise = common::SimNoise::default();
    let a = common::simulate_with(0.5, 3, noise, None, single);
    let b = common::simulate_with(0.5, 3, noise, None, default);
    assert!(b.inputs.flat_frames.len() == 16 && a.inputs.flat_frames.is_empty());
    let green = CornerOptions {
        image: CornerImage::Green,
        ..CornerOptions::default()
    };
    let before = common::pooled_rms(&common::detected_corner_errors(&a, &green, true));
    let after = common::pooled_rms(&common::detected_corner_errors(
        &b,
        &CornerOptions::default(),
        true,
    ));
    println!("corner error rms: single green {before:.4} px, protocol {after:.4} px");
    assert!(after < 0.6 * before, "before {before}, after {after}");
}
