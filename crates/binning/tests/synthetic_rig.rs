//! Binning against an ideal rig written independently here: a distortion-free pinhole camera, a
//! point lamp on a circle, and images rendered directly from an analytic BRDF.

use binning::PositionSamples;
use binning::{bin_samples, BinningOptions};
use binning::{compare, lamp_constant_from_reference, rerender, ForwardOptions, Rates};
use binning::{RigGeometry, SphereView, V3};
use brdf::{bin_angles, bin_coords, MerlTable, BINS};
use brdf::{Brdf, HalfDiff};

struct IdealRig {
    width: usize,
    height: usize,
    f: f64,
    cam: V3,
}

impl IdealRig {
    fn new() -> Self {
        Self {
            width: 160,
            height: 120,
            f: 2600.0,
            cam: V3::new(0.0, -1.0, 0.0),
        }
    }
    // Camera looks along +y; image x = world x, image y = -world z.
    fn basis(&self) -> (V3, V3, V3) {
        (V3::x(), -V3::z(), V3::y())
    }
}

impl RigGeometry for IdealRig {
    fn sensor_size(&self) -> (usize, usize) {
        (self.width, self.height)
    }
    fn pixel_ray(&self, u: f64, v: f64) -> (V3, V3) {
        let (x, y, z) = self.basis();
        let cx = (self.width as f64 - 1.0) / 2.0;
        let cy = (self.height as f64 - 1.0) / 2.0;
        let d = x * ((u - cx) / self.f) + y * ((v - cy) / self.f) + z;
        (self.cam, d.normalize())
    }
    fn project(&self, p: &V3) -> Option<[f64; 2]> {
        let (x, y, z) = self.basis();
        let q = p - self.cam;
        let depth = q.dot(&z);
        (depth > 0.0).then(|| {
            [
                self.f * q.dot(&x) / depth + (self.width as f64 - 1.0) / 2.0,
                self.f * q.dot(&y) / depth + (self.height as f64 - 1.0) / 2.0,
            ]
        })
    }
    fn lamp_position(&self, angle_deg: f64) -> V3 {
        let a = angle_deg.to_radians();
        V3::new(0.5 * a.sin(), 0.5 * a.cos(), 0.0)
    }
    fn sphere(&self) -> (V3, f64) {
        (V3::zeros(), 0.0254)
    }
}

const K: [f64; 3] = [2.0e5, 3.0e5, 1.5e5];

/// Rates of the ideal sphere under the lamp at `angle`, computed per pixel from the BRDF.
fn render(rig: &IdealRig, brdf: &dyn Brdf, angle: f64) -> (Vec<f32>, Vec<bool>) {
    let n = rig.width * rig.height;
    let mut rate = vec![0.0f32; n];
    let mut valid = vec![false; n];
    let (c, r) = rig.sphere();
    let lamp = rig.lamp_position(angle);
    for y in 0..rig.height {
        for x in 0..rig.width {
            let (o, d) = rig.pixel_ray(x as f64, y as f64);
            let Some(t) = binning::ray_sphere(&o, &d, &c, r) else {
                continue;
            };
            let p = o + d * t;
            let nrm = (p - c).normalize();
            let l = lamp - p;
            let wi = l.normalize();
            let cos_i = nrm.dot(&wi);
            let i = y * rig.width + x;
            valid[i] = true;
            if cos_i <= 0.0 {
                continue;
            }
            // Local frame with the normal as z (any tangent: the BRDF is isotropic).
            let t1 = nrm.cross(&V3::new(0.3, 0.5, 0.8)).normalize();
            let t2 = nrm.cross(&t1);
            let loc = |w: &V3| V3::new(w.dot(&t1), w.dot(&t2), w.dot(&nrm));
            let f = brdf.eval(&loc(&wi), &loc(&-d));
            let ch = (y % 2) * 2 + (x % 2);
            let ch = [0, 1, 1, 2][ch];
            rate[i] = (K[ch] * f[ch] * cos_i / l.norm_squared()) as f32;
        }
    }
    (rate, valid)
}

fn rggb(x: usize, y: usize) -> usize {
    [0, 1, 1, 2][(y % 2) * 2 + (x % 2)]
}

fn capture(
    rig: &IdealRig,
    brdf: &dyn Brdf,
    k: &[f64; 3],
    angles: &[f64],
) -> (SphereView, Vec<PositionSamples>) {
    capture_with_ambient(rig, brdf, k, angles, 0.0)
}

fn capture_with_ambient(
    rig: &IdealRig,
    brdf: &dyn Brdf,
    k: &[f64; 3],
    angles: &[f64],
    ambient: f32,
) -> (SphereView, Vec<PositionSamples>) {
    let view = SphereView::new(rig, rggb, 85.0);
    let positions = angles
        .iter()
        .enumerate()
        .map(|(i, &a)| {
            let (mut rate, valid) = render(rig, brdf, a);
            rate.iter_mut().for_each(|r| *r += ambient);
            let samples = binning::position_samples(
                &view,
                Rates {
                    rate: &rate,
                    valid: &valid,
                },
                &rig.lamp_position(a),
                k,
                &ForwardOptions::default(),
            )
            .unwrap();
            PositionSamples {
                position: i as u32,
                angle_deg: a,
                samples,
            }
        })
        .collect();
    (view, positions)
}

#[test]
fn white_reference_recovers_the_lamp_constant() {
    let rig = IdealRig::new();
    let white = brdf::analytic::Lambert {
        kd: [0.98, 0.97, 0.99],
    };
    let view = SphereView::new(&rig, rggb, 85.0);
    let imgs: Vec<(Vec<f32>, Vec<bool>, V3)> = [0.0, 30.0, 60.0]
        .iter()
        .map(|&a| {
            let (r, v) = render(&rig, &white, a);
            (r, v, rig.lamp_position(a))
        })
        .collect();
    let refs: Vec<(Rates, V3)> = imgs
        .iter()
        .map(|(r, v, l)| (Rates { rate: r, valid: v }, *l))
        .collect();
    let k = lamp_constant_from_reference(&view, &refs, white.kd).unwrap();
    for c in 0..3 {
        assert!((k[c] / K[c] - 1.0).abs() < 1e-5, "{k:?}");
    }
}

#[test]
fn lambertian_sphere_bins_to_its_albedo_everywhere_it_is_seen() {
    let rig = IdealRig::new();
    let lambert = brdf::analytic::Lambert {
        kd: [0.6, 0.3, 0.1],
    };
    let angles: Vec<f64> = (0..40).map(|i| i as f64 * 4.0).collect();
    let (view, positions) = capture(&rig, &lambert, &K, &angles);
    let binned = bin_samples(positions.as_slice(), &BinningOptions::default()).unwrap();
    assert!(binned.coverage() > 0.001, "coverage {}", binned.coverage());
    for c in 0..3 {
        for b in 0..BINS {
            if binned.table.is_valid(c, b) {
                let v = binned.table.get(c, b);
                let expect = lambert.kd[c] / std::f64::consts::PI;
                assert!(
                    (v / expect - 1.0).abs() < 1e-4,
                    "ch {c} bin {b}: {v} vs {expect}"
                );
            }
        }
    }
    // Re-rendering from the table reproduces the images.
    // The lamp at 128° (a captured position) lights most of the visible hemisphere.
    let (rate, valid) = render(&rig, &lambert, 128.0);
    let re = rerender(
        &view,
        &binned.table,
        &rig.lamp_position(128.0),
        &K,
        ForwardOptions::default().assignment,
    );
    let err = compare(
        &view,
        &re,
        Rates {
            rate: &rate,
            valid: &valid,
        },
    )
    .unwrap();
    assert!(err.pixels > 1000 && err.median_abs_log < 1e-4, "{err:?}");
}

#[test]
fn glossy_sphere_bins_close_to_the_true_table() {
    let rig = IdealRig::new();
    let glossy = brdf::analytic::Ggx {
        kd: [0.3, 0.2, 0.1],
        ks: [0.5; 3],
        alpha: 0.3,
        ior: 1.5,
    };
    let angles: Vec<f64> = (0..60).map(|i| i as f64 * 2.75).collect();
    let (_, positions) = capture(&rig, &glossy, &K, &angles);
    let binned = bin_samples(positions.as_slice(), &BinningOptions::default()).unwrap();
    // Compare with the BRDF at each covered bin's centre (the samples spread over the bin).
    let mut errs = Vec::new();
    for c in 0..3 {
        for b in 0..BINS {
            if !binned.table.is_valid(c, b) || binned.counts[c * BINS + b] < 2 {
                continue;
            }
            let (i, j, k) = bin_coords(b);
            let lo = bin_angles(i, j, k);
            let hi = bin_angles(i + 1, j + 1, k + 1);
            let mid = HalfDiff::isotropic(
                0.5 * (lo.0 + hi.0),
                0.5 * (lo.1 + hi.1),
                0.5 * (lo.2 + hi.2),
            );
            let truth = glossy.eval_half_diff(&mid)[c];
            if truth > 0.0 {
                errs.push((binned.table.get(c, b) / truth).ln().abs());
            }
        }
    }
    errs.sort_by(|a, b| a.total_cmp(b));
    let median = errs[errs.len() / 2];
    assert!(errs.len() > 1000, "{} bins", errs.len());
    assert!(median < 0.02, "median |log error| {median}");
    let _ = MerlTable::missing();
}

#[test]
fn stray_light_is_estimated_from_the_shadowed_side_and_removed() {
    let rig = IdealRig::new();
    let lambert = brdf::analytic::Lambert {
        kd: [0.5, 0.4, 0.3],
    };
    // Positions where part of the visible sphere is in shadow.
    let angles: Vec<f64> = (0..20).map(|i| 20.0 + i as f64 * 4.0).collect();
    let (_, positions) = capture_with_ambient(&rig, &lambert, &K, &angles, 40.0);
    let binned = bin_samples(positions.as_slice(), &BinningOptions::default()).unwrap();
    let mut n = 0;
    for c in 0..3 {
        for b in 0..BINS {
            if binned.table.is_valid(c, b) {
                let v = binned.table.get(c, b);
                let expect = lambert.kd[c] / std::f64::consts::PI;
                assert!((v / expect - 1.0).abs() < 1e-3, "ch {c}: {v} vs {expect}");
                n += 1;
            }
        }
    }
    assert!(n > 1000);
    // Without the correction the same data is biased upwards.
    let view = SphereView::new(&rig, rggb, 85.0);
    let (mut rate, valid) = render(&rig, &lambert, 60.0);
    rate.iter_mut().for_each(|r| *r += 40.0);
    let opts = ForwardOptions {
        subtract_ambient: false,
        ..Default::default()
    };
    let raw = binning::position_samples(
        &view,
        Rates {
            rate: &rate,
            valid: &valid,
        },
        &rig.lamp_position(60.0),
        &K,
        &opts,
    )
    .unwrap();
    let biased = raw
        .iter()
        .filter(|s| {
            let c = s.key as usize / BINS;
            s.value as f64 > 1.001 * lambert.kd[c] / std::f64::consts::PI
        })
        .count();
    assert!(biased > raw.len() / 2, "{biased} of {}", raw.len());
}

/// Lamp-off frames whose ambient signal (0.3 DN/s) is far below one pixel's noise: averaged over
/// the sphere, the difference of a long and a short exposure recovers it, black level and all.
#[test]
fn ambient_from_lamp_off_frames_recovers_a_signal_below_the_pixel_noise() {
    use rand::{Rng, SeedableRng};
    let rig = IdealRig::new();
    let view = SphereView::new(&rig, rggb, 85.0);
    let truth = [0.3, 0.25, 0.4];
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(5);
    let mut frame = |t: f64| -> Vec<u16> {
        (0..rig.width * rig.height)
            .map(|i| {
                let c = rggb(i % rig.width, i / rig.width);
                // Black level 4 DN, read noise 1 DN, the ambient signal, rounding.
                let dn: f64 = 4.0 + truth[c] * t + rng.gen_range(-1.7..1.7);
                dn.round().max(0.0) as u16
            })
            .collect()
    };
    let (long, short) = (frame(20.0), frame(5.0));
    let est = binning::ambient_from_lamp_off(&view, &long, 20.0, &short, 5.0, &|_| true).unwrap();
    for c in 0..3 {
        assert!(
            (est[c] - truth[c]).abs() < 0.02,
            "channel {c}: {} vs {}",
            est[c],
            truth[c]
        );
    }
    // Hot pixels left out do not count; wrong sizes and exposure order are errors.
    let mut hot = long.clone();
    hot[view.pixels[0].index as usize] = 1023;
    let skip = view.pixels[0].index as usize;
    let est2 =
        binning::ambient_from_lamp_off(&view, &hot, 20.0, &short, 5.0, &|i| i != skip).unwrap();
    assert!((est2[0] - truth[0]).abs() < 0.02 && (est2[1] - truth[1]).abs() < 0.02);
    assert!(
        binning::ambient_from_lamp_off(&view, &long[1..], 20.0, &short, 5.0, &|_| true).is_err()
    );
    assert!(binning::ambient_from_lamp_off(&view, &short, 5.0, &long, 20.0, &|_| true).is_err());
}
