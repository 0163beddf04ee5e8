//! Renders the figure helpers with shared NBRDF materials and writes EXR + PNG files.
//!
//! `cargo run --release -p render --example figures -- <out_dir> [spp]`

use brdf::Brdf;
use render::SpecResolver;
use render::*;
use render::{sphere_scene, strip_scene, teapot_scene};
use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::time::Instant;

fn material(name: &str) -> Material {
    let spec = format!("merl:{name}");
    let brdf = SpecResolver.spec(&spec).expect("material");
    let table: Arc<dyn Brdf> = SpecResolver
        .tabulated(&spec, &brdf)
        .expect("tabulate")
        .unwrap_or(brdf);
    let mut m = Material::with_importance(table, ImportanceResolution::default());
    m.name = name.to_string();
    m
}

fn save(img: &Image, dir: &Path, name: &str, exposure: f64) {
    img.write_exr(&dir.join(format!("{name}.exr"))).unwrap();
    let tm = Tonemap {
        exposure,
        operator: TonemapOperator::Clamp,
    };
    img.write_png(&dir.join(format!("{name}.png")), &tm)
        .unwrap();
}

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let dir = PathBuf::from(args.get(1).cloned().unwrap_or_else(|| "figures".into()));
    let spp: u32 = args.get(2).and_then(|s| s.parse().ok()).unwrap_or(64);
    std::fs::create_dir_all(&dir).unwrap();
    let direct = RenderOptions {
        spp: 16,
        integrator: Integrator::Direct,
        ..Default::default()
    };
    let path = RenderOptions {
        spp,
        ..Default::default()
    };
    for name in ["nickel", "chrome", "blue-acrylic", "gold-metallic-paint"] {
        let t = Instant::now();
        let m = material(name);
        let scene = sphere_scene(m.into(), 256, 256).unwrap();
        let img = render_scene(&scene, &direct).unwrap();
        save(&img, &dir, &format!("sphere-{name}"), 1.0);
        println!("sphere {name}: {:.2}s", t.elapsed().as_secs_f64());
    }
    let env = EnvironmentMap::procedural_probe(512, 256, 1).unwrap();
    save(env.image(), &dir, "probe", 1.0);
    for name in ["nickel", "blue-acrylic", "gold-metallic-paint"] {
        let t = Instant::now();
        let ground = Material::new(Arc::new(Lambert { kd: [0.4; 3] }));
        let scene = teapot_scene(
            material(name).into(),
            Some(env.clone()),
            Some(ground.into()),
            320,
            240,
        )
        .unwrap();
        let img = render_scene(&scene, &path).unwrap();
        save(&img, &dir, &format!("teapot-{name}"), 1.0);
        println!("teapot {name}: {:.2}s", t.elapsed().as_secs_f64());
    }
    // rust teapot: steel blended with a rough brown material by fractal noise
    let rust = SurfaceMaterial::Blend {
        a: material("steel"),
        b: material("light-brown-fabric"),
        mask: Mask::Noise {
            scale: 3.0,
            seed: 5,
            threshold: 0.45,
            softness: 0.12,
        },
    };
    let scene = teapot_scene(rust, Some(env.clone()), None, 320, 240).unwrap();
    let img = render_scene(&scene, &path).unwrap();
    save(&img, &dir, "teapot-rust", 1.0);
    // strip: linear blends between two materials along a path
    let a = material("blue-acrylic");
    let b = material("gold-metallic-paint");
    let strip: Vec<SurfaceMaterial> = (0..7)
        .map(|i| SurfaceMaterial::Blend {
            a: a.clone(),
            b: b.clone(),
            mask: Mask::Constant(i as f64 / 6.0),
        })
        .collect();
    let scene = strip_scene(strip, 96).unwrap();
    let img = render_scene(&scene, &direct).unwrap();
    save(&img, &dir, "strip", 1.0);
}
