//! How much of a capture's table error comes from binning itself: every sphere pixel of every lamp
//! position gets the *exact* BRDF value of its own (ωi, ωo) (no camera, no noise, true geometry), the
//! samples are binned like a capture's, and the table is compared with the material tabulated at the
//! bin centres.
//!
//! `cargo run --release -p binning --example binning_bias -- merl:chrome 0.5 330`

use anyhow::Result;
use binning::{half_diff, lighting, merl_bin};
use binning::{PositionSamples, Sample, SphereView};
use brdf::Brdf;

fn main() -> Result<()> {
    let args: Vec<String> = std::env::args().collect();
    let spec = args.get(1).cloned().unwrap_or("merl:chrome".into());
    let scale: f64 = args.get(2).map_or(Ok(0.5), |s| s.parse())?;
    let n: usize = args.get(3).map_or(Ok(330), |s| s.parse())?;
    let angles = gantry_hal::position_angles(n);
    let nearest = args.get(4).is_some_and(|s| s == "nearest");
    let material = brdf::load(&spec)?;
    let mut cfg = hal_sim::SimConfig::with_scale(scale);
    cfg.material = spec.clone();
    let sim = hal_sim::SimRig::from_config(cfg)?;
    let cal = sim.truth().geometry();
    cal.validate()?;
    let pattern = gantry_hal::BayerPattern::Rggb;
    let view = SphereView::new(&cal, move |x, y| pattern.channel_at(x, y), 85.0);
    let cos_max = 87f64.to_radians().cos();
    let positions: Vec<PositionSamples> = (0..n)
        .map(|i| {
            let angle = angles[i];
            let lamp = binning::RigGeometry::lamp_position(&cal, angle);
            let samples = view
                .pixels
                .iter()
                .filter_map(|p| {
                    let l = lighting(p, &lamp);
                    if l.cos_i < cos_max {
                        return None;
                    }
                    let hd = half_diff(p, &l.to_lamp);
                    let ch = p.channel as usize;
                    let f = material.eval_half_diff(&hd)[ch];
                    let bin = if nearest {
                        nearest_bin(&hd)
                    } else {
                        merl_bin(&hd)
                    };
                    Some(Sample::new(ch, bin, f as f32))
                })
                .collect();
            PositionSamples {
                position: i as u32,
                angle_deg: angle,
                samples,
            }
        })
        .collect();
    let binned = binning::bin_samples(positions.as_slice(), &binning::BinningOptions::default())?;
    if args.get(6).is_some_and(|s| s == "offsets") {
        offset_experiment(&view, &cal, material.as_brdf(), n, cos_max, &args);
    }
    let truth = if args.get(5).is_some_and(|s| s == "sym") {
        brdf::MerlTable::tabulate(&Symmetrised(material.as_brdf()))
    } else {
        material.tabulate()
    };
    let mut errs = Vec::new();
    let mut signed = Vec::new();
    for ch in 0..3 {
        for b in 0..brdf::BINS {
            let (m, tv) = (binned.table.get(ch, b), truth.get(ch, b));
            if m > 0.0 && tv > 0.0 {
                errs.push((m / tv).ln().abs());
                signed.push((m / tv).ln());
            }
        }
    }
    errs.sort_by(f64::total_cmp);
    signed.sort_by(f64::total_cmp);
    let q = |v: &[f64], f: f64| v[((v.len() as f64 * f) as usize).min(v.len() - 1)];
    println!(
        "{spec} scale {scale} positions {n}: coverage {:.3}, median |log| {:.4}, p90 {:.4}, median signed {:+.4}",
        binned.coverage(),
        q(&errs, 0.5),
        q(&errs, 0.9),
        q(&signed, 0.5)
    );
    Ok(())
}

/// The bin whose grid node (θh = (i/90)²·π/2, θd = j/90·π/2, φd = k/180·π) is nearest.
fn nearest_bin(hd: &brdf::HalfDiff) -> usize {
    use std::f64::consts::{FRAC_PI_2, PI};
    let uh = (hd.theta_h.max(0.0) / FRAC_PI_2).sqrt() * 90.0;
    let ud = hd.theta_d.max(0.0) / FRAC_PI_2 * 90.0;
    let mut p = hd.phi_d.rem_euclid(PI);
    if p.is_nan() {
        p = 0.0;
    }
    let up = p / PI * 180.0;
    let i = (uh.round() as usize).min(89);
    let j = (ud.round() as usize).min(89);
    let k = (up.round() as usize) % 180;
    brdf::bin_index(i, j, k)
}

struct Symmetrised<'a>(&'a dyn Brdf);
impl Brdf for Symmetrised<'_> {
    fn eval(&self, wi: &brdf::Vec3, wo: &brdf::Vec3) -> brdf::Rgb {
        let a = self.0.eval(wi, wo);
        let b = self.0.eval(wo, wi);
        [
            0.5 * (a[0] + b[0]),
            0.5 * (a[1] + b[1]),
            0.5 * (a[2] + b[2]),
        ]
    }
    fn name(&self) -> String {
        self.0.name()
    }
}

fn continuous(hd: &brdf::HalfDiff) -> [f64; 3] {
    use std::f64::consts::{FRAC_PI_2, PI};
    [
        (hd.theta_h.max(0.0) / FRAC_PI_2).sqrt() * 90.0,
        hd.theta_d.max(0.0) / FRAC_PI_2 * 90.0,
        hd.phi_d.rem_euclid(PI) / PI * 180.0,
    ]
}

/// Plain mean per node, and the same corrected to first order with the mean sample offset and the
/// log-gradient of the first table (central differences).
fn offset_experiment(
    view: &SphereView,
    cal: &gantry_hal::RigGeometry,
    material: &dyn Brdf,
    n: usize,
    cos_max: f64,
    args: &[String],
) {
    use brdf::{bin_coords, bin_index, BINS};
    let keys = 3 * BINS;
    let mut sum = vec![0f64; keys];
    let mut cnt = vec![0u32; keys];
    let mut off = vec![[0f64; 3]; keys];
    for angle in gantry_hal::position_angles(n) {
        let lamp = binning::RigGeometry::lamp_position(cal, angle);
        for p in &view.pixels {
            let l = lighting(p, &lamp);
            if l.cos_i < cos_max {
                continue;
            }
            let hd = half_diff(p, &l.to_lamp);
            let ch = p.channel as usize;
            let f = material.eval_half_diff(&hd)[ch];
            let u = continuous(&hd);
            let bin = nearest_bin(&hd);
            let (a, b, c) = bin_coords(bin);
            let mut d = [u[0] - a as f64, u[1] - b as f64, u[2] - c as f64];
            if d[2] > 90.0 {
                d[2] -= 180.0;
            }
            let key = ch * BINS + bin;
            sum[key] += f;
            cnt[key] += 1;
            for q in 0..3 {
                off[key][q] += d[q];
            }
        }
    }
    let mean: Vec<f64> = (0..keys)
        .map(|k| {
            if cnt[k] > 0 {
                sum[k] / cnt[k] as f64
            } else {
                -1.0
            }
        })
        .collect();
    let logv = |k: usize| {
        if mean[k] > 0.0 {
            Some(mean[k].ln())
        } else {
            None
        }
    };
    let mut corrected = mean.clone();
    for key in 0..keys {
        if cnt[key] == 0 {
            continue;
        }
        let ch = key / BINS;
        let (a, b, c) = bin_coords(key % BINS);
        let idx = [a as i64, b as i64, c as i64];
        let lim = [90i64, 90, 180];
        let mut g = [0f64; 3];
        for q in 0..3 {
            let mut lo = idx;
            let mut hi = idx;
            lo[q] -= 1;
            hi[q] += 1;
            let wrap = |v: [i64; 3]| -> Option<usize> {
                let mut v = v;
                if q == 2 {
                    v[2] = v[2].rem_euclid(180);
                }
                if v[q] < 0 || v[q] >= lim[q] {
                    return None;
                }
                Some(ch * BINS + bin_index(v[0] as usize, v[1] as usize, v[2] as usize))
            };
            let here = logv(key).unwrap();
            g[q] = match (wrap(lo).and_then(logv), wrap(hi).and_then(logv)) {
                (Some(l), Some(h)) => 0.5 * (h - l),
                (None, Some(h)) => h - here,
                (Some(l), None) => here - l,
                _ => 0.0,
            };
        }
        let m = cnt[key] as f64;
        let corr: f64 = (0..3).map(|q| g[q] * off[key][q] / m).sum();
        corrected[key] = (mean[key].ln() - corr).exp();
    }
    let truth = if args.get(5).is_some_and(|s| s == "sym") {
        brdf::MerlTable::tabulate(&Symmetrised(material))
    } else {
        brdf::MerlTable::tabulate(material)
    };
    for (name, t) in [("plain mean", &mean), ("first-order corrected", &corrected)] {
        let mut e: Vec<f64> = (0..keys)
            .filter(|&k| t[k] > 0.0 && truth.get(k / BINS, k % BINS) > 0.0)
            .map(|k| (t[k] / truth.get(k / BINS, k % BINS)).ln().abs())
            .collect();
        e.sort_by(f64::total_cmp);
        println!(
            "{name}: median {:.4}, p90 {:.4}",
            e[e.len() / 2],
            e[e.len() * 9 / 10]
        );
    }
}
