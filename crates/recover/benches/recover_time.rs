//! Time of one recovery from a 512 × 512 photo of a sphere under the real light probe
//! (functionals + fit), on a Nielsen material rendered by `render`.
//!
//! ```text
//! RECOVER_MODEL=model.bin cargo bench -p recover --bench recover_time
//! ```
//! `RECOVER_SIZE` changes the image size (default 512), `RECOVER_COARSE` the coarse-to-fine
//! row count (`RecoverOptions::coarse_rows`; 0 = every fit on all rows), `RECOVER_REFINE` the
//! iterations of the refinement on all rows (`RecoverOptions::refine_iterations`).

use std::path::Path;
use std::sync::Arc;
use std::time::Instant;

use recover::{Components, FunctionalOptions, Functionals, Observation, Photo, RecoveryScene};

/// User + system CPU seconds of this process so far (Linux `/proc/self/stat`, 100 ticks/s),
/// or NaN elsewhere.
fn cpu_seconds() -> f64 {
    brdf::cpu_seconds().unwrap_or(f64::NAN)
}

fn main() {
    let Ok(model_path) = std::env::var("RECOVER_MODEL") else {
        eprintln!("set RECOVER_MODEL to a model file built by `gantry model build`");
        std::process::exit(2);
    };
    let size: usize = std::env::var("RECOVER_SIZE")
        .ok()
        .and_then(|s| s.parse().ok())
        .unwrap_or(512);
    let model = reduce::Model::load(&model_path).expect("model");
    let probe = brdf::data_dir().join("real/envmap/venice_sunset_1k.exr");
    let text = format!(
        "[camera]\nposition = [0.0, 0.0, 4.0]\nlook_at = [0.0, 0.0, 0.0]\nfov = 32.0\n\
         width = {size}\nheight = {size}\n[[objects]]\nkind = \"sphere\"\n\
         center = [0.0, 0.0, 0.0]\nradius = 1.0\nmaterial = \"object\"\n\
         [environment]\npath = \"{}\"\n",
        probe.display()
    );
    let scene = RecoveryScene::parse(&text, Path::new(".")).expect("scene");
    let truth = brdf::load("nielsen:bindercover")
        .expect("shared data")
        .tabulate();
    let rendered = render::render_scene(
        &scene.with_material(render::Material::with_importance(
            Arc::new(truth.clone()),
            render::ImportanceResolution::default(),
        )),
        &render::RenderOptions {
            spp: 16,
            integrator: render::Integrator::Direct,
            ..Default::default()
        },
    )
    .expect("render");
    let photo = Photo::from_image(&rendered);
    let t = Instant::now();
    let cpu0 = cpu_seconds();
    let f = Functionals::build(&scene, &FunctionalOptions::default()).expect("functionals");
    let tf = t.elapsed().as_secs_f64();
    let obs = vec![Observation::checked(0, f, &photo, None, false).expect("observation")];
    let rec = recover::recover(
        &model,
        &obs,
        &recover::RecoverOptions {
            components: Components::Fixed(45),
            coarse_rows: std::env::var("RECOVER_COARSE")
                .ok()
                .and_then(|s| s.parse().ok())
                .unwrap_or(recover::RecoverOptions::default().coarse_rows),
            refine_iterations: std::env::var("RECOVER_REFINE")
                .ok()
                .and_then(|s| s.parse().ok())
                .unwrap_or(recover::RecoverOptions::default().refine_iterations),
            ..Default::default()
        },
    )
    .expect("recovery");
    let total = t.elapsed().as_secs_f64();
    let cpu = cpu_seconds() - cpu0;
    let truth_err = recover::cosine_weighted_relative_rms(&truth, &rec.table);
    println!(
        "recover {size}x{size} env map: functionals {tf:.1} s, total {total:.1} s wall, \
         {cpu:.1} s CPU ({} rows, {} iterations, {} threads; table error {truth_err:.4})",
        obs[0].functionals.len(),
        rec.fit.iterations,
        rayon::current_num_threads()
    );
    let loadavg = std::fs::read_to_string("/proc/loadavg").unwrap_or_default();
    println!("load average: {}", loadavg.trim());
}
