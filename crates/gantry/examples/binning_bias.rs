//! How much of a capture's table error comes from binning itself: every sphere pixel of every lamp
//! position gets the *exact* BRDF value of its own (ωi, ωo) (no camera, no noise, true geometry), the
//! samples are binned like a capture's, and the table is compared with the material tabulated at the
//! bin centres.
//!
//! `cargo run --release -p gantry --example binning_bias -- merl:chrome 0.5 330`

use anyhow::Result;
use binning::forward::{half_diff, lighting, merl_bin};
use binning::{PositionSamples, Sample, SphereView};
use brdf::Brdf;

fn main() -> Result<()> {
    let args: Vec<String> = std::env::args().collect();
    let spec = args.get(1).cloned().unwrap_or("merl:chrome".into());
    let scale: f64 = args.get(2).map_or(Ok(0.5), |s| s.parse())?;
    let n: usize = args.get(3).map_or(Ok(330), |s| s.parse())?;
    let nearest = args.get(4).is_some_and(|s| s == "nearest");
    let material = brdf::spec::load(&spec)?;
    let mut cfg = hal_sim::SimConfig::with_scale(scale);
    cfg.material = spec.clone();
    let sim = hal_sim::SimRig::from_config(cfg)?;
    let t = sim.truth();
    let c = &t.camera;
    let cal = calib::Calibration::from_fields(
        (c.width, c.height, c.fx, c.fy, c.cx, c.cy, c.k1, c.k2),
        t.pose.rotation,
        t.pose.translation,
        t.lamp.circle.centre,
        t.lamp.circle.normal,
        t.lamp.circle.radius,
        t.lamp.circle.reference,
        t.sphere.centre,
        t.sphere.radius,
    )?;
    let pattern = gantry_hal::BayerPattern::Rggb;
    let view = SphereView::new(&cal, move |x, y| pattern.channel_at(x, y), 85.0);
    let cos_max = 87f64.to_radians().cos();
    let positions: Vec<PositionSamples> = (0..n)
        .map(|i| {
            let angle = 164.5 * i as f64 / (n.max(2) - 1) as f64;
            let lamp = binning::geometry::RigGeometry::lamp_position(&cal, angle);
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
    let truth = if args.get(5).is_some_and(|s| s == "sym") {
        brdf::MerlTable::tabulate(&Symmetrised(material.as_brdf()))
    } else {
        material.tabulate()
    };
    let mut errs = Vec::new();
    let mut signed = Vec::new();
    for ch in 0..3 {
        for b in 0..brdf::table::BINS {
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
    brdf::table::bin_index(i, j, k)
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
