//! The thesis's four materials (§3.7, fig. 3-8): Lafortune (shared shape and the thesis's
//! per-channel form), Ward, GGX and two-lobe GGX fitted in log space on 2,000 random bins (the
//! thesis's 6,000 values) and both Lafortune forms on every valid bin; errors on every valid
//! bin in three readings of the thesis's log error; a polar plot of the incidence plane per
//! material and the fitted specs in `thesis-fits.txt`.
//!
//! ```text
//! cargo run --release -p fit --example thesis_materials -- [docs/img/fit] [--quick]
//! ```

use brdf::{Brdf, Spherical};
use fit::{
    fit, log_readings, EvalRows, FitData, FitOptions, ModelKind, Objective, Parametric, Subset,
};
use plotters::prelude::*;
use std::path::PathBuf;

const MATERIALS: [(&str, f64); 4] = [
    ("yellow-paint", 5.0),
    ("blue-metallic-paint", 10.0),
    ("specular-orange-phenolic", 12.0),
    ("nickel", 21.0),
];

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let mut args: Vec<String> = std::env::args().skip(1).collect();
    // `--quick`: skip the fits on every valid bin (≈ 500× the cost of a 2,000-bin fit).
    let quick = args.iter().any(|a| a == "--quick");
    args.retain(|a| a != "--quick");
    // Starts of the multi-start (default 4).
    let starts: usize = std::env::var("FIT_STARTS")
        .ok()
        .and_then(|s| s.parse().ok())
        .unwrap_or(4);
    let out = PathBuf::from(args.first().cloned().unwrap_or("docs/img/fit".into()));
    std::fs::create_dir_all(&out)?;
    println!("| material | thesis | model | fitted on | log error (ours) | plain-ln relative | plain-ln mean abs | RMS log ratio |");
    println!("|---|---|---|---|---|---|---|---|");
    let mut specs = String::new();
    for (name, thesis) in MATERIALS {
        let table = brdf::load(&format!("merl:{name}"))?.tabulate();
        let data = FitData::new(&table)?;
        let eval = EvalRows::new(&data)?;
        let sub = FitOptions {
            objective: Objective::Log,
            subset: Subset::Random {
                bins: 2000,
                seed: 7,
            },
            starts,
            ..FitOptions::default()
        };
        let all = FitOptions {
            subset: Subset::All,
            starts: 1,
            ..sub
        };
        let mut fits = Vec::new();
        for kind in [
            ModelKind::Lafortune1,
            ModelKind::LafortuneRgb,
            ModelKind::Ward,
            ModelKind::Ggx,
            ModelKind::Ggx2,
        ] {
            fits.push((kind, "2,000 bins", fit(kind, &data, &sub)?.model));
            if !quick && matches!(kind, ModelKind::Lafortune1 | ModelKind::LafortuneRgb) {
                fits.push((kind, "all bins", fit(kind, &data, &all)?.model));
            }
        }
        for (kind, on, m) in &fits {
            let r = log_readings(&data, m);
            println!(
                "| {name} | {thesis:.0} % | {} | {on} | {:.1} % | {:.1} % | {:.1} % | {:.1} % |",
                kind.name(),
                100.0 * eval.errors(m).log,
                100.0 * r.plain_relative,
                100.0 * r.mean_abs_relative,
                100.0 * r.rms_log_ratio
            );
            if *on == "2,000 bins" {
                specs.push_str(&format!("{name} {} {}\n", kind.name(), m.spec()));
            }
        }
        let pick = |k: ModelKind| {
            fits.iter()
                .find(|(kind, on, _)| *kind == k && *on == "2,000 bins")
                .map(|(_, _, m)| m)
                .expect("fitted above")
        };
        polar_plot(
            &out.join(format!("{name}-incidence-plane.png")),
            name,
            &table,
            &[
                ("Lafortune", pick(ModelKind::Lafortune1)),
                ("Ward", pick(ModelKind::Ward)),
                ("GGX 2-lobe", pick(ModelKind::Ggx2)),
                ("Lafortune per channel", pick(ModelKind::LafortuneRgb)),
            ],
        )?;
    }
    let path = out.join("thesis-fits.txt");
    brdf::write_atomic(&path, specs.as_bytes())?;
    eprintln!("fitted material specs: {}", path.display());
    Ok(())
}

/// Incidence plane at θi = 45°: radius log10(f) + 4 (clamped at 0) against θo, measured (black)
/// and each fitted model, green channel.
fn polar_plot(
    path: &std::path::Path,
    _title: &str,
    table: &brdf::MerlTable,
    models: &[(&str, &Parametric)],
) -> Result<(), Box<dyn std::error::Error>> {
    let wi = Spherical::new(45f64.to_radians(), 0.0).to_vector();
    let curve = |b: &dyn Brdf| -> Vec<(f64, f64)> {
        (-89..=89)
            .map(|deg| {
                let t = (deg as f64).to_radians();
                let wo = Spherical::new(t.abs(), if t < 0.0 { 0.0 } else { std::f64::consts::PI })
                    .to_vector();
                let r = (b.eval(&wi, &wo)[1].max(1e-4).log10() + 4.0).max(0.0);
                (r * t.sin(), r * t.cos())
            })
            .collect()
    };
    let (w, h) = (640u32, 400u32);
    let mut buf = vec![0u8; (w * h * 3) as usize];
    {
        let root = BitMapBackend::with_buffer(&mut buf, (w, h)).into_drawing_area();
        root.fill(&WHITE)?;
        // No text: the plot backend is built without fonts (colours are listed in docs/fit.md).
        let mut chart = ChartBuilder::on(&root)
            .margin(10)
            .build_cartesian_2d(-7.0f64..7.0, 0.0f64..7.0)?;
        for r in 1..=6 {
            let ring: Vec<(f64, f64)> = (0..=180)
                .map(|d| {
                    let a = (d as f64 - 90.0).to_radians();
                    (r as f64 * a.sin(), r as f64 * a.cos())
                })
                .collect();
            chart.draw_series(LineSeries::new(ring, RGBColor(220, 220, 220)))?;
        }
        let colours = [RED, BLUE, RGBColor(0, 150, 0), RGBColor(230, 140, 0)];
        for ((_, m), c) in models.iter().zip(colours) {
            chart.draw_series(LineSeries::new(curve(*m), c.stroke_width(2)))?;
        }
        chart.draw_series(LineSeries::new(curve(table), BLACK.stroke_width(3)))?;
        root.present()?;
    }
    let img = image::RgbImage::from_raw(w, h, buf).ok_or("image buffer")?;
    brdf::write_atomic_with(path, |f| {
        img.write_to(f, image::ImageFormat::Png)
            .map_err(std::io::Error::other)
    })?;
    Ok(())
}
