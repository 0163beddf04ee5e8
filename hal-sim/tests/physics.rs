//! Radiometric and sensor-model properties of the simulated rig.

use brdf::analytic::Lambert;
use hal_sim::{SimConfig, SimRig};
use nalgebra::Vector3;
use std::sync::Arc;
use std::time::Duration;

const T: Duration = Duration::from_secs(3600);

fn lambert_rig(scale: f64, seed: u64) -> SimRig {
    let mut cfg = SimConfig::with_scale(scale);
    cfg.seed = seed;
    cfg.lamp.warm_up_s = 0.0;
    SimRig::new(
        cfg,
        Arc::new(Lambert {
            kd: [0.5, 0.4, 0.3],
        }),
    )
    .unwrap()
}

fn ready(rig: &SimRig, angle: f64) -> gantry_hal::Rig {
    let mut r = rig.rig();
    r.turntable.home(T).unwrap();
    r.turntable.move_to(angle, T).unwrap();
    r.lamp.set_on(true).unwrap();
    r.lamp.wait_stable(T).unwrap();
    r
}

/// Exposure times of the thesis's series: 18 steps, 40 µs to 20 s, geometric.
fn seed_exposures() -> Vec<f64> {
    let r = (20.0f64 / 40e-6).powf(1.0 / 17.0);
    (0..18).map(|k| 40e-6 * r.powi(k)).collect()
}

#[test]
fn ground_truth_radiance_matches_an_independent_lambert_computation() {
    let rig = lambert_rig(0.08, 3);
    // Only the serialised ground truth is used for the independent computation.
    let truth: hal_sim::SceneTruth =
        serde_json::from_str(&serde_json::to_string(rig.truth()).unwrap()).unwrap();
    let angle = 120.0;
    let pt = rig.position_truth(angle);
    let cam = truth.camera;
    let c = truth.pose.centre();
    let sc = Vector3::from(truth.sphere.centre);
    let lamp = truth.lamp.circle.position(angle);
    let kd = [0.5, 0.4, 0.3];
    let mut checked = 0;
    for y in 0..cam.height {
        for x in 0..cam.width {
            let i = y * cam.width + x;
            let ch = gantry_hal::BayerPattern::Rggb.channel_at(x, y);
            let d = truth.pose.dir_to_world(&cam.ray(x as f64, y as f64));
            // Ray-sphere intersection by the quadratic formula, written out afresh.
            let oc = c - sc;
            let (a, b, cc) = (
                d.dot(&d),
                2.0 * oc.dot(&d),
                oc.dot(&oc) - truth.sphere.radius.powi(2),
            );
            let disc = b * b - 4.0 * a * cc;
            let stray = truth.stray_radiance[ch];
            let expected = if disc > 0.0 {
                let t = (-b - disc.sqrt()) / (2.0 * a);
                let p = c + t * d;
                let n = (p - sc).normalize();
                let l = lamp - p;
                let cos = n.dot(&l.normalize()).max(0.0);
                let e = truth.lamp.radiant_intensity[ch] * cos
                    / (l.norm_squared() + truth.lamp.disc_radius.powi(2));
                kd[ch] / std::f64::consts::PI * e + stray
            } else {
                stray
            };
            let got = pt.radiance[i] as f64;
            assert!(
                (got - expected).abs() <= 1e-5 * expected.max(1e-3),
                "pixel ({x},{y}): {got} vs {expected}"
            );
            checked += disc.is_sign_positive() as usize;
        }
    }
    assert!(checked > 500, "sphere covers {checked} pixels");
}

#[test]
fn irradiance_follows_inverse_square_and_foreshortening() {
    let rig = lambert_rig(0.05, 1);
    let lamp = rig.truth().lamp;
    let p0 = lamp.circle.position(37.0);
    let centre = Vector3::from(lamp.circle.centre);
    let towards = (p0 - centre).normalize();
    // A patch facing the lamp at distance d and at 2d: irradiance ratio 4 (up to the disc term).
    let a2 = lamp.disc_radius.powi(2);
    let e = |d: f64, tilt: f64| {
        let p = p0 - towards * d;
        let axis = towards.cross(&Vector3::z()).normalize();
        let n = nalgebra::Rotation3::from_axis_angle(&nalgebra::Unit::new_normalize(axis), tilt)
            * towards;
        lamp.irradiance(37.0, &p, &n)[1]
    };
    let r = e(0.2, 0.0) / e(0.4, 0.0);
    assert!((r - (0.16 + a2) / (0.04 + a2)).abs() < 1e-12);
    let f = e(0.3, 1.0) / e(0.3, 0.0);
    assert!((f - 1.0f64.cos()).abs() < 1e-12);
    assert_eq!(e(0.3, 2.0), 0.0, "lamp below the horizon");
}

#[test]
fn frames_are_bit_identical_for_a_seed_and_any_thread_count() {
    let grab = |threads: usize, seed: u64| {
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap();
        pool.install(|| {
            let rig = lambert_rig(0.1, seed);
            let mut r = ready(&rig, 90.0);
            r.camera.set_exposure(0.3).unwrap();
            let a = r.camera.capture(T).unwrap();
            let b = r.camera.capture(T).unwrap();
            (a, b)
        })
    };
    let (a1, b1) = grab(1, 5);
    let (a2, b2) = grab(2, 5);
    assert_eq!(a1, a2);
    assert_eq!(b1, b2);
    assert_ne!(a1.data, b1.data, "successive frames carry fresh noise");
    let (a3, _) = grab(2, 6);
    assert_ne!(a1.data, a3.data, "another seed gives another frame");
}

#[test]
fn naive_multi_exposure_merge_reproduces_ground_truth_radiance() {
    let rig = lambert_rig(0.1, 11);
    let angle = 100.0;
    let mut r = ready(&rig, angle);
    let exposures = seed_exposures();
    let frames: Vec<_> = exposures
        .iter()
        .map(|&t| {
            r.camera.set_exposure(t).unwrap();
            r.camera.capture(T).unwrap()
        })
        .collect();
    let truth = rig.position_truth(angle);
    let tr = rig.truth();
    let s = &tr.sensor;
    let (w, npx) = (tr.camera.width, tr.camera.width * tr.camera.height);
    let mut rel_errs = Vec::new();
    for i in 0..npx {
        if !truth.on_sphere[i] || truth.signal_rate_dn_per_s[i] < 5.0 {
            continue;
        }
        // The thesis's merge: keep 10..=1000 DN, fit a line DN = a + b t, slope = rate.
        let pts: Vec<(f64, f64)> = frames
            .iter()
            .map(|f| (f.exposure_s, f.data[i] as f64))
            .filter(|(_, v)| (10.0..=1000.0).contains(v))
            .collect();
        if pts.len() < 2 {
            continue;
        }
        let n = pts.len() as f64;
        let mt = pts.iter().map(|p| p.0).sum::<f64>() / n;
        let mv = pts.iter().map(|p| p.1).sum::<f64>() / n;
        let stt: f64 = pts.iter().map(|p| (p.0 - mt).powi(2)).sum();
        let stv: f64 = pts.iter().map(|p| (p.0 - mt) * (p.1 - mv)).sum();
        let slope = stv / stt;
        let ch = gantry_hal::BayerPattern::Rggb.channel_at(i % w, i / w);
        // DN/s -> radiance with the nominal sensor constants (PRNU and dark current ignored).
        let radiance = slope * s.gain_e_per_dn / (s.quantum_efficiency[ch] * s.responsivity);
        let gt = truth.radiance[i] as f64;
        rel_errs.push((radiance - gt).abs() / gt);
    }
    assert!(rel_errs.len() > 1000, "{} merged pixels", rel_errs.len());
    rel_errs.sort_by(|a, b| a.partial_cmp(b).unwrap());
    let median = rel_errs[rel_errs.len() / 2];
    let p95 = rel_errs[rel_errs.len() * 95 / 100];
    eprintln!(
        "HDR merge: {} pixels, median relative error {median:.4}, 95th percentile {p95:.4}",
        rel_errs.len()
    );
    assert!(median < 0.015, "median relative error {median}");
    assert!(p95 < 0.05, "95th percentile relative error {p95}");
}

#[test]
fn photon_transfer_mean_and_variance_follow_the_sensor_model() {
    let rig = lambert_rig(0.2, 21);
    let angle = 60.0;
    let mut r = ready(&rig, angle);
    let truth = rig.position_truth(angle);
    let s = rig.truth().sensor.clone();
    let g = s.gain_e_per_dn;
    let k = 4;
    // Bins of expected mean signal: (sum of sample variances, predicted, count, mean dev).
    let mut pairs: Vec<(f64, f64)> = Vec::new();
    for &t in &[0.02, 0.05, 0.1, 0.2, 0.4, 0.8, 1.6] {
        r.camera.set_exposure(t).unwrap();
        let frames: Vec<_> = (0..k).map(|_| r.camera.capture(T).unwrap()).collect();
        for i in 0..truth.radiance.len() {
            let mu_e = truth.signal_rate_dn_per_s[i] as f64 * t * g;
            let mean_dn = s.black_level_dn + mu_e / g;
            if !truth.on_sphere[i] || !(30.0..900.0).contains(&mean_dn) {
                continue;
            }
            let xs: Vec<f64> = frames.iter().map(|f| f.data[i] as f64).collect();
            let m = xs.iter().sum::<f64>() / k as f64;
            let v = xs.iter().map(|x| (x - m).powi(2)).sum::<f64>() / (k - 1) as f64;
            pairs.push((mean_dn, v));
            let _ = m;
        }
    }
    assert!(pairs.len() > 2000, "{} pixels", pairs.len());
    // Bin by expected mean and compare the average variance with the model
    // σ² = μ_e/g² + σ_read²/g² + 1/12.
    let edges = [30.0, 100.0, 250.0, 500.0, 900.0];
    let mut xs = Vec::new();
    let mut ys = Vec::new();
    for b in 0..edges.len() - 1 {
        let sel: Vec<_> = pairs
            .iter()
            .filter(|(m, _)| *m >= edges[b] && *m < edges[b + 1])
            .collect();
        eprintln!("bin {b}: {} pixels", sel.len());
        if sel.len() < 300 {
            continue;
        }
        let mean_signal =
            sel.iter().map(|(m, _)| m - s.black_level_dn).sum::<f64>() / sel.len() as f64;
        let var = sel.iter().map(|(_, v)| v).sum::<f64>() / sel.len() as f64;
        let model = mean_signal / g + (s.read_noise_e / g).powi(2) + 1.0 / 12.0;
        eprintln!("bin {b}: variance {var:.3}, model {model:.3}");
        assert!(
            (var / model - 1.0).abs() < 0.08,
            "bin {b}: variance {var} vs model {model}"
        );
        xs.push(mean_signal);
        ys.push(var);
    }
    assert!(xs.len() >= 3);
    // Photon-transfer slope = 1/gain.
    let n = xs.len() as f64;
    let mx = xs.iter().sum::<f64>() / n;
    let my = ys.iter().sum::<f64>() / n;
    let slope = xs
        .iter()
        .zip(&ys)
        .map(|(x, y)| (x - mx) * (y - my))
        .sum::<f64>()
        / xs.iter().map(|x| (x - mx).powi(2)).sum::<f64>();
    eprintln!("PTC gain {:.3} e-/DN (model {g})", 1.0 / slope);
    assert!(
        (slope * g - 1.0).abs() < 0.06,
        "PTC gain {} vs {g}",
        1.0 / slope
    );
}

#[test]
fn frame_means_follow_the_expected_signal() {
    let rig = lambert_rig(0.2, 4);
    let mut r = ready(&rig, 75.0);
    let truth = rig.position_truth(75.0);
    let s = rig.truth().sensor.clone();
    let t = 0.4;
    r.camera.set_exposure(t).unwrap();
    let frames: Vec<_> = (0..4).map(|_| r.camera.capture(T).unwrap()).collect();
    let (mut sum_obs, mut sum_exp, mut n) = (0.0, 0.0, 0);
    for i in 0..truth.radiance.len() {
        let e = s.black_level_dn + truth.signal_rate_dn_per_s[i] as f64 * t;
        if !(20.0..900.0).contains(&e) {
            continue;
        }
        for f in &frames {
            sum_obs += f.data[i] as f64;
            sum_exp += e;
            n += 1;
        }
    }
    assert!(n > 4000);
    assert!(
        (sum_obs / sum_exp - 1.0).abs() < 2e-3,
        "{} vs {}",
        sum_obs / n as f64,
        sum_exp / n as f64
    );
}

#[test]
fn saturation_and_black_level() {
    let rig = lambert_rig(0.08, 2);
    let mut r = ready(&rig, 90.0);
    r.camera.set_exposure(60.0).unwrap();
    let f = r.camera.capture(T).unwrap();
    let truth = rig.position_truth(90.0);
    let lit: Vec<usize> = (0..f.data.len())
        .filter(|&i| truth.signal_rate_dn_per_s[i] > 100.0)
        .collect();
    assert!(!lit.is_empty() && lit.iter().all(|&i| f.data[i] == 1023));
    assert!(f.data.iter().all(|&v| v <= 1023));
    // Lens covered, shortest exposure: only black level and read noise.
    let d = r.camera.capture_dark(40e-6, T).unwrap();
    let mean = d.data.iter().map(|&v| v as f64).sum::<f64>() / d.data.len() as f64;
    assert!(
        (mean - rig.truth().sensor.black_level_dn).abs() < 0.05,
        "{mean}"
    );
}

#[test]
fn sixty_second_dark_frame_finds_exactly_the_hot_pixels() {
    let rig = lambert_rig(0.3, 8);
    let mut r = rig.rig();
    let dark = r.camera.capture_dark(60.0, T).unwrap();
    let found: Vec<(usize, usize)> = (0..dark.data.len())
        .filter(|&i| dark.data[i] > 16)
        .map(|i| (i % dark.width, i / dark.width))
        .collect();
    let truth = rig.hot_pixels();
    assert!(truth.len() >= 5, "{} hot pixels", truth.len());
    assert_eq!(found, truth);
    // Dark current grows with exposure: the hot pixels are dimmer in a 6 s frame.
    let short = r.camera.capture_dark(6.0, T).unwrap();
    let sum =
        |f: &gantry_hal::BayerFrame| truth.iter().map(|&(x, y)| f.get(x, y) as f64).sum::<f64>();
    assert!(sum(&short) < 0.3 * sum(&dark));
}

#[test]
fn dark_current_grows_with_temperature() {
    let mut cold = SimConfig::with_scale(0.3);
    cold.sensor.temperature_c = 10.0;
    let mut warm = cold.clone();
    warm.sensor.temperature_c = 35.0;
    let k = Arc::new(Lambert { kd: [0.5; 3] });
    let mean_dark = |cfg: SimConfig| {
        let rig = SimRig::new(cfg, k.clone()).unwrap();
        let f = rig.rig().camera.capture_dark(60.0, T).unwrap();
        f.data.iter().map(|&v| v as f64).sum::<f64>() / f.data.len() as f64
    };
    let black = cold.sensor.black_level_dn;
    let (c, w) = (mean_dark(cold.clone()), mean_dark(warm));
    // 25 °C more is 2^(25/6.3) ≈ 15.6 times the dark current.
    assert!(w - black > 5.0 * (c - black), "cold {c}, warm {w}");
}

#[test]
fn reduced_resolution_keeps_the_field_of_view() {
    let full = SimConfig::default();
    let k = Arc::new(Lambert { kd: [0.5; 3] });
    let small = SimRig::new(SimConfig::with_scale(0.1), k).unwrap();
    let c = small.truth().camera;
    assert_eq!((c.width, c.height), (130, 103));
    let fov = |w: usize, f: f64| 2.0 * ((w as f64 / 2.0) / f).atan();
    assert!((fov(c.width, c.fx) - fov(full.camera.width, full.camera.fx)).abs() < 1e-9);
    // The sphere's image shrinks with the scale: area ≈ 1% of the full-resolution one.
    let frac = small.scene().sphere_pixel_count() as f64 / (c.width * c.height) as f64;
    assert!(
        frac > 0.1 && frac < 0.5,
        "sphere covers {frac} of the image"
    );
}

#[test]
fn projection_and_ray_are_inverse() {
    let rig = lambert_rig(1.0, 1);
    let cam = rig.truth().camera;
    for &(u, v) in &[(0.0, 0.0), (1299.0, 1029.0), (650.0, 515.0), (17.3, 900.2)] {
        let d = cam.ray(u, v);
        let p = cam.project_camera_point(&(d * 2.0)).unwrap();
        assert!(
            (p[0] - u).abs() < 1e-6 && (p[1] - v).abs() < 1e-6,
            "{p:?} vs ({u},{v})"
        );
    }
}

#[test]
fn clock_accounts_for_a_full_capture_of_330_positions_and_18_exposures() {
    let mut cfg = SimConfig::with_scale(0.02);
    cfg.lamp.warm_up_s = 600.0;
    let rig = SimRig::new(cfg.clone(), Arc::new(Lambert { kd: [0.5; 3] })).unwrap();
    let mut r = rig.rig();
    let exposures = seed_exposures();
    r.turntable.home(T).unwrap();
    r.lamp.set_on(true).unwrap();
    r.lamp.wait_stable(T).unwrap();
    let t0 = r.clock.now().as_secs_f64();
    for p in 0..330 {
        r.turntable.move_to(p as f64 * 0.5, T).unwrap();
        for &e in &exposures {
            r.camera.set_exposure(e).unwrap();
            r.camera.capture(T).unwrap();
        }
    }
    let spent = r.clock.now().as_secs_f64() - t0;
    let tm = &cfg.timing;
    let expected = 330.0 * (exposures.iter().sum::<f64>() + 18.0 * tm.readout_s)
        + 329.0 * (0.5 / tm.turntable_speed_deg_per_s)
        + 330.0 * tm.settle_s;
    assert!(
        (spent - expected).abs() < 1e-6 * expected,
        "{spent} vs {expected}"
    );
    // The thesis's rig took about four hours.
    assert!(
        (3.0 * 3600.0..5.0 * 3600.0).contains(&spent),
        "{} h",
        spent / 3600.0
    );
    eprintln!("simulated 330 x 18 capture: {:.2} h", spent / 3600.0);
}

#[test]
fn lamp_warm_up_reduces_the_signal_until_stable() {
    let mut cfg = SimConfig::with_scale(0.08);
    cfg.lamp.warm_up_s = 100.0;
    let rig = SimRig::new(cfg, Arc::new(Lambert { kd: [0.5; 3] })).unwrap();
    let mut r = rig.rig();
    r.turntable.home(T).unwrap();
    r.turntable.move_to(90.0, T).unwrap();
    r.lamp.set_on(true).unwrap();
    assert!(matches!(
        r.lamp.state().unwrap(),
        gantry_hal::LampState::WarmingUp { .. }
    ));
    r.camera.set_exposure(0.3).unwrap();
    let early = r.camera.capture(T).unwrap();
    assert!(r.lamp.wait_stable(Duration::from_secs(10)).is_err());
    r.lamp.wait_stable(T).unwrap();
    assert_eq!(r.lamp.state().unwrap(), gantry_hal::LampState::Stable);
    let late = r.camera.capture(T).unwrap();
    let sum = |f: &gantry_hal::BayerFrame| f.data.iter().map(|&v| v as f64 - 4.0).sum::<f64>();
    let ratio = sum(&early) / sum(&late);
    assert!(ratio < 0.95 && ratio > 0.85, "{ratio}");
}

#[test]
fn defocus_blur_conserves_light_and_softens_the_limb() {
    let k = Arc::new(Lambert { kd: [0.5; 3] });
    let sharp_cfg = SimConfig::with_scale(0.15);
    let mut blur_cfg = sharp_cfg.clone();
    blur_cfg.sensor.defocus_sigma_px = 1.5;
    let sharp = SimRig::new(sharp_cfg, k.clone())
        .unwrap()
        .position_truth(90.0);
    let blurred = SimRig::new(blur_cfg, k).unwrap().position_truth(90.0);
    let total = |v: &[f32]| v.iter().map(|&x| x as f64).sum::<f64>();
    let (a, b) = (total(&sharp.radiance), total(&blurred.radiance));
    // The sphere is far from the image border, so the blur only moves light around.
    assert!((a / b - 1.0).abs() < 2e-3, "{a} vs {b}");
    let w = 195;
    let max_step = |v: &[f32]| {
        (0..v.len() - 2)
            .filter(|i| i % w < w - 2)
            .map(|i| (v[i + 2] - v[i]).abs())
            .fold(0f32, f32::max)
    };
    assert!(max_step(&blurred.radiance) < 0.6 * max_step(&sharp.radiance));
}
