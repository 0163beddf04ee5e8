//! Helpers shared by the simulator-based tests: a small simulated rig and series capture
//! through the `gantry-hal` device traits.

#![allow(dead_code)]

use gantry_hal::{BayerFrame, Rig};
use hal_sim::{SimConfig, SimRig};
use std::sync::Arc;
use std::time::Duration;

pub const T: Duration = Duration::from_secs(3600);

/// The glossy test material.
pub const GLOSSY: &str = "phong:kd=0.2,ks=0.6,n=60";

/// The simulated rig's configuration at sensor `scale`, seeded, with a lamp `lamp_gain` times
/// the default that needs no warm-up.
pub fn config(scale: f64, seed: u64, lamp_gain: f64) -> SimConfig {
    let mut cfg = SimConfig::with_scale(scale);
    cfg.seed = seed;
    cfg.lamp.warm_up_s = 0.0;
    cfg.lamp.radiant_intensity = cfg.lamp.radiant_intensity.map(|i| i * lamp_gain);
    cfg
}

/// A rig of configuration `cfg` with a sphere of material `spec` (see `brdf::spec`).
pub fn rig(cfg: SimConfig, spec: &str) -> SimRig {
    let material = brdf::load(spec).expect("material spec");
    SimRig::new(cfg, Arc::new(material)).expect("simulated rig")
}

/// A reduced-resolution rig with a glossy sphere, a lamp `lamp_gain` times the default and a
/// fraction `hot_fraction` of hot pixels.
pub fn glossy_rig(scale: f64, seed: u64, lamp_gain: f64, hot_fraction: f64) -> SimRig {
    let mut cfg = config(scale, seed, lamp_gain);
    cfg.sensor.hot_pixel_fraction = hot_fraction;
    rig(cfg, GLOSSY)
}

/// Homes the turntable and switches the lamp on.
pub fn ready(sim: &SimRig) -> Rig {
    let mut r = sim.rig();
    r.turntable.home(T).unwrap();
    r.lamp.set_on(true).unwrap();
    r.lamp.wait_stable(T).unwrap();
    r
}

/// The defect map of a 60 s dark frame.
pub fn dark_defects(rig: &mut Rig) -> hdr::DefectMap {
    let dark = rig.camera.capture_dark(60.0, T).unwrap();
    hdr::DefectMap::from_dark_frame(&dark, &hdr::DarkFrameOptions::default()).unwrap()
}

/// The bracketing planner's settings for a camera whose black level the defect map measured.
pub fn plan_options(defects: &hdr::DefectMap) -> hdr::BracketOptions {
    hdr::BracketOptions {
        black_level_dn: defects.dark_median_dn(),
        ..Default::default()
    }
}

/// The merge of `frames` with the given intercept and default settings otherwise.
pub fn merge_with(
    frames: &[BayerFrame],
    defects: &hdr::DefectMap,
    intercept: hdr::Intercept,
) -> hdr::HdrImage {
    let opts = hdr::MergeOptions {
        intercept,
        ..Default::default()
    };
    hdr::merge(frames, Some(defects), &opts).unwrap()
}

/// Two merges of one position (the full ladder and the planned series) against the truth over
/// a region of interest: how many pixels are valid in the full merge and in both, and the
/// relative errors of both over the pixels valid in both.
#[derive(Debug, Default)]
pub struct Agreement {
    /// Region pixels valid in the full merge.
    pub full_valid: usize,
    /// Region pixels valid in both merges.
    pub both_valid: usize,
    /// Relative errors of the full merge.
    pub err_full: Vec<f64>,
    /// Relative errors of the planned merge.
    pub err_adaptive: Vec<f64>,
}

/// Compares the full and planned merges of a position with its true signal rates.
pub fn agreement(
    full: &hdr::HdrImage,
    adaptive: &hdr::HdrImage,
    roi: &[bool],
    truth: &hal_sim::PositionTruth,
) -> Agreement {
    let mut a = Agreement::default();
    for (i, &inside) in roi.iter().enumerate() {
        if !inside || !full.valid[i] {
            continue;
        }
        a.full_valid += 1;
        if adaptive.valid[i] {
            a.both_valid += 1;
            let t = truth.signal_rate_dn_per_s[i] as f64;
            a.err_full.push((full.radiance[i] as f64 - t).abs() / t);
            a.err_adaptive
                .push((adaptive.radiance[i] as f64 - t).abs() / t);
        }
    }
    a
}

/// Moves to `angle` and captures one frame per exposure.
pub fn capture_series(rig: &mut Rig, angle: f64, exposures: &[f64]) -> Vec<BayerFrame> {
    rig.turntable.move_to(angle, T).unwrap();
    exposures
        .iter()
        .map(|&e| {
            rig.camera.set_exposure(e).unwrap();
            rig.camera.capture(T).unwrap()
        })
        .collect()
}

/// The `q`-quantile (0..=1) of `xs` (sorted copy, nearest rank).
pub fn quantile(xs: &[f64], q: f64) -> f64 {
    let mut v: Vec<f64> = xs.to_vec();
    v.sort_by(f64::total_cmp);
    let k = ((v.len() - 1) as f64 * q).round() as usize;
    v[k]
}

/// Sphere pixels whose incidence and view angles are both at most `max_deg` for the lamp at
/// `angle_deg`, by ray–sphere intersection from the scene's ground-truth geometry.
pub fn measurement_region(truth: &hal_sim::SceneTruth, angle_deg: f64, max_deg: f64) -> Vec<bool> {
    use nalgebra::Vector3;
    let cam = truth.camera;
    let c = truth.pose.centre();
    let sc = Vector3::from(truth.sphere.centre);
    let r = truth.sphere.radius;
    let lamp = truth.lamp.circle.position(angle_deg);
    let cos_max = max_deg.to_radians().cos();
    let mut roi = vec![false; cam.width * cam.height];
    for y in 0..cam.height {
        for x in 0..cam.width {
            let d = truth.pose.dir_to_world(&cam.ray(x as f64, y as f64));
            let oc = c - sc;
            let b = oc.dot(&d);
            let disc = b * b - (oc.norm_squared() - r * r);
            if disc <= 0.0 {
                continue;
            }
            let p = c + (-b - disc.sqrt()) * d;
            let n = (p - sc) / r;
            let cos_o = n.dot(&(-d));
            let cos_i = n.dot(&(lamp - p).normalize());
            roi[y * cam.width + x] = cos_o >= cos_max && cos_i >= cos_max;
        }
    }
    roi
}
