//! Tabulation benchmark: decode every shared neural BRDF (96 MERL + 8 Nielsen) onto the
//! 90 × 90 × 180 MERL grid and report the total and the per-material median.
//!
//! Run: `cargo bench -p brdf --bench tabulate` (set `BRDF_DATA_DIR` if the data is elsewhere).

use brdf::nbrdf;
use std::time::Instant;

fn main() {
    let root = brdf::data_dir().join("nbrdf");
    let mut materials = Vec::new();
    for set in ["merl", "nielsen"] {
        match nbrdf::load_dir(root.join(set)) {
            Ok(m) => materials.extend(m),
            Err(e) => {
                eprintln!("cannot load {set}: {e}");
                std::process::exit(1);
            }
        }
    }
    let threads = rayon::current_num_threads();
    let mut times = Vec::new();
    let start = Instant::now();
    let mut checksum = 0.0f64;
    for m in &materials {
        let t0 = Instant::now();
        let table = m.tabulate_f32();
        times.push(t0.elapsed().as_secs_f64());
        checksum += table[12345] as f64;
    }
    let total = start.elapsed().as_secs_f64();
    times.sort_by(|a, b| a.total_cmp(b));
    let median = times[times.len() / 2];
    println!(
        "tabulated {} materials ({} threads): total {:.2} s, median {:.1} ms/material, {:.1} M BRDF values/s (checksum {checksum:.4})",
        materials.len(),
        threads,
        total,
        median * 1e3,
        (materials.len() * 3 * brdf::BINS) as f64 / total / 1e6,
    );
}
