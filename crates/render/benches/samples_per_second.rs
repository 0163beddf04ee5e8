//! Samples per second on standard scenes (harness-free benchmark; prints a table).
//!
//! `cargo bench -p render --bench samples_per_second`
//!
//! Standard scene: the Utah teapot (tabulated nickel, A.2.4 importance tables) on a grey
//! Lambertian ground under the procedural light probe, 160 × 120 pixels, path tracing with
//! MIS, max depth 8.

use brdf::Brdf;
use render::SpecResolver;
use render::*;
use render::{sphere_scene, teapot_scene};
use std::sync::Arc;
use std::time::Instant;

fn nickel() -> Material {
    let spec = "merl:nickel";
    let brdf = SpecResolver
        .spec(spec)
        .expect("shared data (set BRDF_DATA_DIR)");
    let table: Arc<dyn Brdf> = SpecResolver.tabulated(spec, &brdf).unwrap().unwrap_or(brdf);
    Material::with_importance(table, ImportanceResolution::default())
}

fn run(label: &str, scene: &Scene, opts: &RenderOptions) {
    // warm-up
    let _ = render_scene(
        scene,
        &RenderOptions {
            spp: 1,
            ..opts.clone()
        },
    )
    .unwrap();
    let t = Instant::now();
    let out = render_with_variance(scene, opts).unwrap();
    let secs = t.elapsed().as_secs_f64();
    println!(
        "| {label} | {}×{} | {} | {:.2} | {:.0} |",
        scene.camera.width,
        scene.camera.height,
        opts.spp,
        secs,
        out.samples as f64 / secs
    );
}

fn main() {
    let threads = rayon::current_num_threads();
    println!("rayon threads: {threads}");
    println!("| scene | size | spp | seconds | camera samples / s |");
    println!("|---|---|---|---|---|");
    let m = nickel();
    let env = EnvironmentMap::procedural_probe(512, 256, 1).unwrap();
    let ground = Material::new(Arc::new(Lambert { kd: [0.4; 3] }));
    let teapot = teapot_scene(m.clone().into(), Some(env), Some(ground.into()), 160, 120).unwrap();
    for (label, sampling) in [
        (
            "teapot path, importance (inversion)",
            BsdfSampling::Importance(PhiSampling::Inversion),
        ),
        (
            "teapot path, importance (rejection)",
            BsdfSampling::Importance(PhiSampling::Rejection),
        ),
        ("teapot path, cosine", BsdfSampling::Cosine),
    ] {
        let opts = RenderOptions {
            spp: 16,
            max_depth: 8,
            bsdf_sampling: sampling,
            ..Default::default()
        };
        run(label, &teapot, &opts);
    }
    let sphere = sphere_scene(m.into(), 256, 256).unwrap();
    run(
        "sphere direct (A.1), point light",
        &sphere,
        &RenderOptions {
            spp: 16,
            integrator: Integrator::Direct,
            ..Default::default()
        },
    );
}
