//! The thesis's chapter-5 figures on the shared MERL corpus (PNG into `docs/img/traits/`):
//! trait scatter plots with navigation paths and names (figs. 5-2 to 5-4), navigation strips
//! in the linear and chart spaces (5-5, 5-6), the steel-oxidation strip (5-7) and a teapot
//! whose texture selects a position along the oxidation path (5-8).
//!
//! `cargo run --release -p traits --example trait_figures -- MODEL.bin [OUT_DIR]`
//! (default `docs/img/traits`; names are drawn with DejaVu Sans from
//! `/usr/share/fonts/truetype/dejavu`, `fonts-dejavu-core` on Debian).
//!
//! Every sphere is a table written by a [`traits::Session`] step or a path point that passed
//! the validity checks; steps that a check stopped are marked in the log.

use std::path::{Path, PathBuf};
use std::sync::Arc;

use plotters::prelude::*;
use render::{render_scene, Integrator, Material, RenderOptions, SurfaceMaterial, Tonemap};
use traits::thesis_labels;
use traits::Session;
use traits::SetFit;
use traits::{path_points, Navigator, NavigatorOptions, PathKind, Space, TraitSet};
use traits::{FitOptions, Method};

type Res<T> = Result<T, Box<dyn std::error::Error>>;

const STEPS: usize = 6;

fn fit(model: &reduce::Model, space: Space) -> Res<TraitSet> {
    let emb = traits::Embedding::new(model, space, 45)?;
    let coords = emb.corpus()?;
    let f = SetFit {
        coords: &coords,
        names: &model.names,
        space,
        options: FitOptions::default(),
        cross_validate: false,
    };
    Ok(f.binary(&thesis_labels(), Method::Svm)?)
}

/// `STEPS` states from `material` adding `step` units of `trait_name` each time.
fn navigation(
    nav: &Navigator,
    set: &TraitSet,
    material: &str,
    trait_name: &str,
    step: f64,
) -> Res<(Vec<brdf::MerlTable>, Vec<Vec<f64>>)> {
    let x = nav.embedding.of_name(material)?;
    let tv = set.get(trait_name)?;
    let mut s = Session::new(nav, &x)?;
    let mut tables = Vec::new();
    let mut coords = Vec::new();
    for i in 0..STEPS {
        if i > 0 {
            let (applied, why) = s.nudge(tv, step)?;
            if let Some(c) = why {
                eprintln!("{material} + {trait_name}: step {i} applied {applied:.3} of {step}, stopped by {c}");
            }
        }
        let (t, report) = s.table()?;
        assert!(report.is_valid(), "{:?}", report.failed);
        tables.push(t);
        coords.push(s.state().coords.clone());
    }
    Ok((tables, coords))
}

fn strip_image(tables: Vec<brdf::MerlTable>, px: usize) -> Res<render::Image> {
    let mats: Vec<SurfaceMaterial> = tables
        .into_iter()
        .map(|t| SurfaceMaterial::Single(Material::new(Arc::new(t))))
        .collect();
    let scene = render::strip_scene(mats, px)?;
    let opts = RenderOptions {
        spp: 4,
        integrator: Integrator::Direct,
        ..Default::default()
    };
    Ok(render_scene(&scene, &opts)?)
}

/// Stacks images vertically and writes a PNG (sRGB, clamp).
fn write_rows(rows: &[render::Image], path: &Path) -> Res<()> {
    let w = rows.iter().map(|r| r.width()).max().unwrap_or(1);
    let h: usize = rows.iter().map(|r| r.height()).sum();
    let mut out = render::Image::new(w, h)?;
    let mut y0 = 0;
    for r in rows {
        for y in 0..r.height() {
            for x in 0..r.width() {
                out.set(x, y0 + y, r.get(x, y));
            }
        }
        y0 += r.height();
    }
    out.write_png(
        path,
        &Tonemap {
            exposure: 1.5,
            ..Default::default()
        },
    )?;
    Ok(())
}

fn scatter(
    path: &Path,
    set: &TraitSet,
    corpus: &nalgebra::DMatrix<f64>,
    names: &[String],
    axes: (&str, &str),
    paths: &[(Vec<Vec<f64>>, RGBColor)],
) -> Res<()> {
    let (tx, ty) = (set.get(axes.0)?, set.get(axes.1)?);
    let pts: Vec<(f64, f64)> = (0..corpus.nrows())
        .map(|i| {
            let x: Vec<f64> = corpus.row(i).iter().copied().collect();
            (tx.direction.score(&x), ty.direction.score(&x))
        })
        .collect();
    let ext = |f: &dyn Fn(&(f64, f64)) -> f64| {
        let lo = pts.iter().map(f).fold(f64::INFINITY, f64::min);
        let hi = pts.iter().map(f).fold(f64::NEG_INFINITY, f64::max);
        let pad = 0.08 * (hi - lo);
        (lo - pad)..(hi + pad)
    };
    let mut buf = vec![0u8; 1400 * 1100 * 3];
    {
        let root = BitMapBackend::with_buffer(&mut buf, (1400, 1100)).into_drawing_area();
        root.fill(&WHITE)?;
        let mut chart = ChartBuilder::on(&root)
            .margin(20)
            .x_label_area_size(50)
            .y_label_area_size(60)
            .caption(
                format!("{} trait vs {} trait (chart space, SVM)", axes.1, axes.0),
                ("sans-serif", 28),
            )
            .build_cartesian_2d(ext(&|p| p.0), ext(&|p| p.1))?;
        chart
            .configure_mesh()
            .x_desc(format!("{} score", axes.0))
            .y_desc(format!("{} score", axes.1))
            .label_style(("sans-serif", 18))
            .draw()?;
        chart.draw_series(pts.iter().zip(names).map(|(p, n)| {
            EmptyElement::at(*p)
                + Circle::new((0, 0), 3, BLACK.filled())
                + Text::new(
                    n.clone(),
                    (4, -4),
                    ("sans-serif", 11).into_font().color(&RGBColor(60, 60, 60)),
                )
        }))?;
        for (coords, color) in paths {
            let line: Vec<(f64, f64)> = coords
                .iter()
                .map(|x| (tx.direction.score(x), ty.direction.score(x)))
                .collect();
            chart.draw_series(LineSeries::new(line.clone(), color.stroke_width(3)))?;
            if let Some(&end) = line.last() {
                chart.draw_series(std::iter::once(Circle::new(end, 6, color.filled())))?;
            }
        }
        root.present()?;
    }
    let img = image::RgbImage::from_raw(1400, 1100, buf).ok_or("buffer size")?;
    let mut png = Vec::new();
    img.write_to(&mut std::io::Cursor::new(&mut png), image::ImageFormat::Png)?;
    brdf::write_atomic(path, &png)?;
    Ok(())
}

fn main() -> Res<()> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let model_path = args.first().ok_or("usage: figures MODEL.bin [OUT_DIR]")?;
    let out = PathBuf::from(args.get(1).map_or("docs/img/traits", |s| s));
    std::fs::create_dir_all(&out)?;
    let font = std::fs::read("/usr/share/fonts/truetype/dejavu/DejaVuSans.ttf")
        .map_err(|e| format!("DejaVuSans.ttf ({e}); install fonts-dejavu-core"))?;
    plotters::style::register_font(
        "sans-serif",
        FontStyle::Normal,
        Box::leak(font.into_boxed_slice()),
    )
    .map_err(|_| "cannot register the font")?;
    let model = reduce::Model::load(model_path)?;
    let px = 128;

    // Fig. 5-5: linear space.
    let lin = fit(&model, Space::Linear)?;
    let nav = Navigator::new(&model, Space::Linear, NavigatorOptions::default())?;
    let mut rows = Vec::new();
    for (m, t, a) in [
        ("gold-metallic-paint", "redness", 0.4),
        ("two-layer-gold", "silverness", 0.3),
        ("specular-blue-phenolic", "gold-like", 0.3),
        ("black-soft-plastic", "specularness", 0.3),
    ] {
        let (tables, _) = navigation(&nav, &lin, m, t, a)?;
        rows.push(strip_image(tables, px)?);
        eprintln!("linear strip {m} + {t} rendered");
    }
    write_rows(&rows, &out.join("fig5-5-linear-navigation.png"))?;
    drop(nav);

    // Fig. 5-6 and the scatter plots 5-2..5-4: chart space.
    let cha = fit(&model, Space::Chart)?;
    let nav = Navigator::new(&model, Space::Chart, NavigatorOptions::default())?;
    let mut rows = Vec::new();
    let mut paths = Vec::new();
    for (m, t, a, color) in [
        ("brass", "roughness", 0.3, RGBColor(120, 120, 120)),
        ("green-acrylic", "blueness", 0.3, RGBColor(0, 160, 0)),
        ("violet-acrylic", "metallic-like", 0.3, RGBColor(0, 0, 220)),
        ("yellow-paint", "glossiness", 0.3, RGBColor(220, 0, 0)),
    ] {
        let (tables, coords) = navigation(&nav, &cha, m, t, a)?;
        rows.push(strip_image(tables, px)?);
        if m != "brass" {
            paths.push((coords, color));
        }
        eprintln!("chart strip {m} + {t} rendered");
    }
    write_rows(&rows, &out.join("fig5-6-chart-navigation.png"))?;
    let corpus = nav.embedding.corpus()?;
    for (file, axes) in [
        (
            "fig5-2-diffuseness-specularness.png",
            ("specularness", "diffuseness"),
        ),
        (
            "fig5-3-metallic-specularness.png",
            ("specularness", "metallic-like"),
        ),
        (
            "fig5-4-glossiness-diffuseness.png",
            ("diffuseness", "glossiness"),
        ),
    ] {
        scatter(&out.join(file), &cha, &corpus, &model.names, axes, &paths)?;
    }

    // Fig. 5-7: oxidation path through the corpus, piecewise in chart space.
    let stops = [
        "chrome-steel",
        "steel",
        "tungsten-carbide",
        "black-oxidized-steel",
    ];
    let pts = stops
        .iter()
        .map(|s| nav.embedding.of_name(s))
        .collect::<Result<Vec<_>, _>>()?;
    let path = path_points(&pts, 8, PathKind::Piecewise)?;
    let mut tables = Vec::new();
    for (i, x) in path.iter().enumerate() {
        let s = nav.state(x)?;
        let f = nav.failures(&s)?;
        let (t, r) = nav.table(&s)?;
        if f.is_empty() && r.is_valid() {
            tables.push(t);
        } else {
            eprintln!(
                "oxidation step {i} invalid ({f:?} {:?}): left out",
                r.failed
            );
        }
    }
    let teapot_tables: Vec<brdf::MerlTable> = tables.clone();
    write_rows(
        &[strip_image(tables, px)?],
        &out.join("fig5-7-oxidation.png"),
    )?;

    // Fig. 5-8: a teapot whose texture (fractal noise) selects the position along the path.
    // The image is a per-pixel blend of renders with the path's materials: rendering is
    // linear in the BRDF, so this equals a spatially varying BRDF under direct lighting.
    let (w, h) = (320, 240);
    let renders = teapot_tables
        .into_iter()
        .map(|t| {
            let scene = render::teapot_scene(
                SurfaceMaterial::Single(Material::new(Arc::new(t))),
                None,
                None,
                w,
                h,
            )?;
            let opts = RenderOptions {
                spp: 8,
                integrator: Integrator::Direct,
                ..Default::default()
            };
            Ok(render_scene(&scene, &opts)?)
        })
        .collect::<Res<Vec<_>>>()?;
    let n = renders.len();
    let mut img = render::Image::new(w, h)?;
    for y in 0..h {
        for x in 0..w {
            let p = brdf::Vec3::new(x as f64 / 40.0, y as f64 / 40.0, 0.5);
            let v = ((render::fbm(&p, 3) - 0.3) / 0.4).clamp(0.0, 1.0) * (n - 1) as f64;
            let i = (v.floor() as usize).min(n - 2);
            let f = (v - i as f64) as f32;
            let (a, b) = (renders[i].get(x, y), renders[i + 1].get(x, y));
            img.set(x, y, [0, 1, 2].map(|c| (1.0 - f) * a[c] + f * b[c]));
        }
    }
    img.write_png(
        &out.join("fig5-8-oxidation-teapot.png"),
        &Tonemap {
            exposure: 1.5,
            ..Default::default()
        },
    )?;
    eprintln!("figures written to {}", out.display());
    Ok(())
}
