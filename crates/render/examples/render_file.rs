//! Renders a TOML scene file to EXR and PNG: the reference for `gantry render scene.toml`.
//!
//! `cargo run --release -p render --example render_file -- scene.toml out.exr [spp]`

use render::{load_scene, SpecResolver};
use render::{render_scene, RenderOptions, Tonemap};
use std::path::PathBuf;
use std::sync::Arc;

fn main() {
    let args: Vec<String> = std::env::args().collect();
    if args.len() < 3 {
        eprintln!("usage: render_file <scene.toml> <out.exr> [spp]");
        std::process::exit(2);
    }
    let loaded = match load_scene(&PathBuf::from(&args[1]), &SpecResolver) {
        Ok(l) => l,
        Err(e) => {
            eprintln!("error: {e}");
            std::process::exit(1);
        }
    };
    let mut opts = RenderOptions::default();
    loaded.defaults.apply(&mut opts).expect("render defaults");
    if let Some(spp) = args.get(3).and_then(|s| s.parse().ok()) {
        opts.spp = spp;
    }
    opts.progress = Some(Arc::new(|done, total| {
        if done == total || done % 50 == 0 {
            eprintln!("tiles {done}/{total}");
        }
    }));
    let t = std::time::Instant::now();
    let img = render_scene(&loaded.scene, &opts).expect("render");
    eprintln!("rendered in {:.2}s", t.elapsed().as_secs_f64());
    let out = PathBuf::from(&args[2]);
    img.write_exr(&out).expect("write exr");
    img.write_png(&out.with_extension("png"), &Tonemap::default())
        .expect("write png");
}
