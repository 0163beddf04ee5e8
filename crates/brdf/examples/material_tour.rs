//! A tour of the `brdf` crate: name materials by spec, evaluate them, tabulate them on the
//! MERL grid, summarise them, and build a small log-space corpus.
//!
//! `cargo run --release -p brdf --example material_tour -- [spec ...]`
//! (default: an analytic GGX, a Lambertian and, when the shared data is present, `merl:chrome`).

use brdf::Corpus;
use brdf::{summarize, SummaryOptions};
use brdf::{Brdf, MerlTable, Spherical};

fn main() -> Result<(), brdf::BrdfError> {
    let mut specs: Vec<String> = std::env::args().skip(1).collect();
    if specs.is_empty() {
        specs = vec![
            "ggx:alpha=0.15,kd=0.05".into(),
            "lambert:kd=0.6/0.4/0.2".into(),
        ];
        if brdf::data_dir().join("nbrdf/merl").is_dir() {
            specs.push("merl:chrome".into());
        }
    }
    // One light 30° off the normal, the viewer mirrored: the specular configuration.
    let wi = Spherical::new(30f64.to_radians(), 0.0).to_vector();
    let wo = Spherical::new(30f64.to_radians(), std::f64::consts::PI).to_vector();
    for spec in &specs {
        let material = brdf::load(spec)?;
        let f = material.eval(&wi, &wo);
        println!(
            "{spec}: f(30°, mirror) = {:.4} {:.4} {:.4} 1/sr",
            f[0], f[1], f[2]
        );
        // The dense table every data-driven method works on, and its summary.
        let table = MerlTable::tabulate(&material);
        let s = summarize(&material, &table, &SummaryOptions::default());
        println!("  {s:?}");
    }
    // The same specs as a corpus of log-space vectors (thesis §4.1).
    let c = Corpus::load(&specs)?;
    println!(
        "corpus: {} materials × {} values; first value of each: {:?}",
        c.len(),
        c.dim(),
        (0..c.len())
            .map(|i| brdf::from_log(c.row(i)[0] as f64))
            .collect::<Vec<_>>()
    );
    Ok(())
}
