//! The thesis's fig. 3-8: for each of its four materials, a strip of spheres under the Venice
//! sunset light probe rendered with the `render` path tracer — the measured table, then each
//! model fitted by the `thesis_materials` example (read from its `thesis-fits.txt`).
//!
//! ```text
//! cargo run --release -p fit --example thesis_materials -- docs/img/fit
//! cargo run --release -p fit --example fig_3_8 -- docs/img/fit [sphere pixels, 96] [spp, 32]
//! ```

use render::{Camera, EnvironmentMap, Integrator, RenderOptions, SceneBuilder, Tonemap};
use render::{Material, SurfaceMaterial, TonemapOperator};
use std::path::PathBuf;
use std::sync::Arc;

/// Strip order after the measured table.
const MODELS: [&str; 5] = ["lafortune", "lafortune-rgb", "ward", "ggx", "ggx2"];

fn material(spec: &str) -> Result<SurfaceMaterial, Box<dyn std::error::Error>> {
    let loaded = brdf::load(spec)?;
    let table = loaded.tabulate();
    let brdf: Arc<dyn brdf::Brdf> = Arc::new(loaded);
    Ok(Material::with_importance_from(brdf, &table, Default::default()).into())
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let dir = PathBuf::from(args.first().cloned().unwrap_or("docs/img/fit".into()));
    let px: usize = args.get(1).map(|s| s.parse()).transpose()?.unwrap_or(96);
    let spp: u32 = args.get(2).map(|s| s.parse()).transpose()?.unwrap_or(32);
    let fits = std::fs::read_to_string(dir.join("thesis-fits.txt")).map_err(|e| {
        format!(
            "{}: {e} (run the thesis_materials example first)",
            dir.display()
        )
    })?;
    let probe = brdf::data_dir().join("real/envmap/venice_sunset_1k.exr");
    let env = EnvironmentMap::read_exr(&probe)?;
    let mut materials: Vec<&str> = Vec::new();
    for line in fits.lines() {
        let name = line.split(' ').next().unwrap_or_default();
        if !materials.contains(&name) {
            materials.push(name);
        }
    }
    for name in materials {
        let mut specs = vec![format!("merl:{name}")];
        for model in MODELS {
            let spec = fits
                .lines()
                .filter_map(|l| l.strip_prefix(&format!("{name} {model} ")))
                .next()
                .ok_or_else(|| format!("{name}: no {model} fit in thesis-fits.txt"))?;
            specs.push(spec.to_string());
        }
        let (n, spacing, distance) = (specs.len(), 2.3, 60.0);
        let cx = (n as f64 - 1.0) * spacing * 0.5;
        let camera = Camera {
            position: brdf::Vec3::new(cx, 0.0, distance),
            look_at: brdf::Vec3::new(cx, 0.0, 0.0),
            up: brdf::Vec3::y(),
            fov_degrees: 2.0 * (spacing * 0.5 / distance).atan().to_degrees(),
            width: px * n,
            height: px,
        };
        let mut b = SceneBuilder::new(camera);
        for (i, spec) in specs.iter().enumerate() {
            let id = b.add_material(material(spec)?);
            b.add_sphere(brdf::Vec3::new(i as f64 * spacing, 0.0, 0.0), 1.0, id)?;
        }
        b.set_environment(env.clone());
        let scene = b.build()?;
        let opts = RenderOptions {
            spp,
            seed: 11,
            integrator: Integrator::PathTracing,
            max_depth: 3,
            ..Default::default()
        };
        let t = std::time::Instant::now();
        let img = render::render_scene(&scene, &opts)?;
        // One exposure per strip: the measured sphere's mean pixel at 0.3 after Reinhard.
        let mut mean = 0.0;
        for y in 0..px {
            for x in 0..px {
                let p = img.get(x, y);
                mean += (p[0] + p[1] + p[2]) as f64 / 3.0;
            }
        }
        mean /= (px * px) as f64;
        let tonemap = Tonemap {
            exposure: if mean > 0.0 { 0.43 / mean } else { 1.0 },
            operator: TonemapOperator::Reinhard,
        };
        let out = dir.join(format!("{name}-fig-3-8.png"));
        img.write_png(&out, &tonemap)?;
        println!(
            "{} ({} × {}, {spp} spp, {:.0} s): {}",
            out.display(),
            px * n,
            px,
            t.elapsed().as_secs_f64(),
            std::iter::once("measured")
                .chain(MODELS)
                .collect::<Vec<_>>()
                .join(", ")
        );
    }
    Ok(())
}
