//! Inverse mapping (thesis §3.5) against forward binning (§3.4) on the simulated rig.
//!
//! For each material the simulator's noise-free signal-rate images (`SimRig::position_truth`:
//! lamp light, stray light, dark current and PRNU, defocus blur; no shot noise, no HDR merge)
//! are turned into a table both ways with the true geometry and a lamp constant measured on a
//! simulated white sphere, and compared with the material's own table.
//!
//! ```sh
//! cargo run --release -p binning --example inverse_vs_forward -- \
//!     [--scale 0.5] [--positions 330] [--materials blue-acrylic,pink-felt,chrome]
//! ```

use binning::PositionSamples;
use binning::{bin_samples, BinningOptions};
use binning::{fill_table, Construction, InverseOptions, InversePosition, PositionChoice};
use binning::{lamp_constant_from_reference, ForwardOptions, Rates};
use binning::{SphereView, V3};
use brdf::{Brdf, HalfDiff, Rgb};
use brdf::{MerlTable, BINS};
use std::time::Instant;

type AnyError = Box<dyn std::error::Error>;

/// The calibration equal to the simulator's truth.
fn true_geometry(sim: &hal_sim::SimRig) -> Result<gantry_hal::RigGeometry, AnyError> {
    let g = sim.truth().geometry();
    g.validate()?;
    Ok(g)
}

/// The thesis's 330 lamp angles from 0° to 164.5°, or `n` spread over the same arc.
fn lamp_angles(n: usize) -> Vec<f64> {
    gantry_hal::position_angles(n)
}

/// ½(f(φd) + f(φd + π)): the material made exactly reciprocal.
struct Reciprocal<'a>(&'a dyn Brdf);

impl Brdf for Reciprocal<'_> {
    fn eval(&self, wi: &brdf::Vec3, wo: &brdf::Vec3) -> Rgb {
        let (a, b) = (self.0.eval(wi, wo), self.0.eval(wo, wi));
        [0, 1, 2].map(|c| 0.5 * (a[c] + b[c]))
    }
    fn eval_half_diff(&self, hd: &HalfDiff) -> Rgb {
        let (a, b) = (
            self.0.eval_half_diff(hd),
            self.0.eval_half_diff(&hd.swapped()),
        );
        [0, 1, 2].map(|c| 0.5 * (a[c] + b[c]))
    }
    fn name(&self) -> String {
        format!("reciprocal {}", self.0.name())
    }
}

struct Errors {
    keys: usize,
    median: f64,
    p90: f64,
}

/// |ln(m / t)| quantiles over keys where `m` is valid (and `mask`, if given) and `t` positive.
fn errors(m: &MerlTable, t: &MerlTable, mask: Option<&MerlTable>) -> Errors {
    let mut e = Vec::new();
    for c in 0..3 {
        for b in 0..BINS {
            if m.is_valid(c, b) && mask.is_none_or(|k| k.is_valid(c, b)) && t.get(c, b) > 0.0 {
                e.push((m.get(c, b) / t.get(c, b)).ln().abs());
            }
        }
    }
    e.sort_by(|a, b| a.total_cmp(b));
    let q = |f: f64| {
        e.get(((e.len() as f64 * f) as usize).min(e.len().saturating_sub(1)))
            .copied()
            .unwrap_or(f64::NAN)
    };
    Errors {
        keys: e.len(),
        median: q(0.5),
        p90: q(0.9),
    }
}

fn coverage(t: &MerlTable) -> f64 {
    1.0 - t.missing_fraction()
}

fn arg(args: &[String], name: &str) -> Option<String> {
    args.iter()
        .position(|a| a == name)
        .and_then(|i| args.get(i + 1).cloned())
}

fn main() -> Result<(), AnyError> {
    let args: Vec<String> = std::env::args().collect();
    let scale: f64 = arg(&args, "--scale").map_or(Ok(0.5), |s| s.parse())?;
    let n_positions: usize = arg(&args, "--positions").map_or(Ok(330), |s| s.parse())?;
    let materials =
        arg(&args, "--materials").unwrap_or_else(|| "blue-acrylic,pink-felt,chrome".into());
    println!("scale {scale}, {n_positions} positions, noise-free simulated rates, true geometry\n");
    println!("| material | method | coverage | median abs log err | p90 | median / p90 vs reciprocal truth | median / p90 on keys both cover | time |");
    println!("|---|---|---|---|---|---|---|---|");
    for name in materials.split(',') {
        let mut cfg = hal_sim::SimConfig::with_scale(scale);
        cfg.material = format!("merl:{name}");
        let sim = hal_sim::SimRig::from_config(cfg.clone())?;
        let geometry = true_geometry(&sim)?;
        let pattern = sim.scene().pattern();
        let view = SphereView::new(&geometry, move |x, y| pattern.channel_at(x, y), 85.0);
        // Lamp constant from a simulated white sphere of albedo 0.99, as `gantry capture` does.
        let mut white_cfg = cfg.clone();
        white_cfg.material = "lambert:kd=0.99".into();
        let white = hal_sim::SimRig::from_config(white_cfg)?;
        let refs: Vec<(Vec<f32>, V3)> = [110.0, 125.0, 140.0, 155.0]
            .into_iter()
            .map(|a| {
                (
                    white.position_truth(a).signal_rate_dn_per_s,
                    geometry.lamp_position(a),
                )
            })
            .collect();
        let all_valid = vec![true; view.width * view.height];
        let ref_rates: Vec<(Rates<'_>, V3)> = refs
            .iter()
            .map(|(r, l)| {
                (
                    Rates {
                        rate: r,
                        valid: &all_valid,
                    },
                    *l,
                )
            })
            .collect();
        let k = lamp_constant_from_reference(&view, &ref_rates, [0.99; 3])?;
        // Render all positions once; keep forward samples and compact inverse positions.
        let inv_opts = InverseOptions::default();
        let mut forward = Vec::new();
        let mut inverse = Vec::new();
        let (mut t_fwd, mut t_inv) = (0.0, 0.0);
        for (i, &a) in lamp_angles(n_positions).iter().enumerate() {
            let truth = sim.position_truth(a);
            let rates = Rates {
                rate: &truth.signal_rate_dn_per_s,
                valid: &all_valid,
            };
            let t0 = Instant::now();
            let samples = binning::position_samples(
                &view,
                rates,
                &geometry.lamp_position(a),
                &k,
                &ForwardOptions::default(),
            )?;
            forward.push(PositionSamples {
                position: i as u32,
                angle_deg: a,
                samples,
            });
            t_fwd += t0.elapsed().as_secs_f64();
            let t0 = Instant::now();
            inverse.push(InversePosition::new(&geometry, &view, a, rates, &inv_opts)?);
            t_inv += t0.elapsed().as_secs_f64();
        }
        let t0 = Instant::now();
        let fwd = bin_samples(forward.as_slice(), &BinningOptions::default())?.table;
        t_fwd += t0.elapsed().as_secs_f64();
        drop(forward);
        let material = brdf::load(&format!("merl:{name}"))?;
        let truth = material.tabulate();
        let reciprocal = MerlTable::tabulate(&Reciprocal(&material));
        let methods = [
            (
                "inverse, circles, nearest (seed)",
                Construction::Circles,
                PositionChoice::Nearest,
            ),
            (
                "inverse, circles, interpolated",
                Construction::Circles,
                PositionChoice::Interpolate,
            ),
            (
                "inverse, half vector, interpolated",
                Construction::HalfVector,
                PositionChoice::Interpolate,
            ),
        ];
        let mut tables = Vec::new();
        for (label, construction, choice) in methods {
            let opts = InverseOptions {
                construction,
                choice,
                ..inv_opts.clone()
            };
            let t0 = Instant::now();
            let table = fill_table(&geometry, &view, &inverse, &k, &opts)?.table;
            tables.push((label, table, t_inv + t0.elapsed().as_secs_f64()));
        }
        let row = |label: &str, t: &MerlTable, other: &MerlTable, secs: f64| {
            let e = errors(t, &truth, None);
            let r = errors(t, &reciprocal, None);
            let both = errors(t, &reciprocal, Some(other));
            println!(
                "| {name} | {label} | {:.1}% | {:.2}% | {:.1}% | {:.2}% / {:.1}% | {:.2}% / {:.1}% ({} keys) | {secs:.1} s |",
                100.0 * coverage(t),
                100.0 * e.median,
                100.0 * e.p90,
                100.0 * r.median,
                100.0 * r.p90,
                100.0 * both.median,
                100.0 * both.p90,
                both.keys
            );
        };
        row("forward binning", &fwd, &tables[2].1, t_fwd);
        for (label, table, secs) in &tables {
            row(label, table, &fwd, *secs);
        }
    }
    Ok(())
}
