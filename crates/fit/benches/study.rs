//! Benchmark of the corpus study: wall time of every shared MERL and Nielsen material × every
//! model × the three objectives, against the target of 10 minutes for the 96 MERL materials on
//! 2 cores (scaled to the number of materials run).
//!
//! ```text
//! RAYON_NUM_THREADS=2 cargo bench -p fit --bench study
//! FIT_STUDY_MATERIALS=4 cargo bench -p fit --bench study   # the first 4 materials only
//! ```
//! The CSV goes to `$CARGO_TARGET_TMPDIR/fit-study-bench.csv`.

use fit::{study_corpus, write_csv, StudyOptions};
use std::time::Instant;

/// Target wall time for the 96 MERL materials (seconds).
const TARGET_96: f64 = 600.0;

fn main() -> Result<(), Box<dyn std::error::Error + Send + Sync>> {
    let max: usize = std::env::var("FIT_STUDY_MATERIALS")
        .ok()
        .map_or(Ok(usize::MAX), |s| s.parse())?;
    let mut materials =
        brdf::nbrdf::shared_materials().map_err(|e| format!("{e} (set BRDF_DATA_DIR)"))?;
    materials.truncate(max);
    let options = StudyOptions::default();
    let t = Instant::now();
    let labels: Vec<String> = materials.iter().map(|(_, _, name)| name.clone()).collect();
    let rows = study_corpus(
        &labels,
        |i| -> fit::Result<_> { Ok(brdf::nbrdf::shared_table(&materials[i])?) },
        &options,
        |_, _| Ok(()),
    )?;
    let wall = t.elapsed().as_secs_f64();
    let out = std::path::Path::new(env!("CARGO_TARGET_TMPDIR")).join("fit-study-bench.csv");
    write_csv(&rows, &out)?;
    let target = TARGET_96 * materials.len() as f64 / 96.0;
    println!(
        "study: {} materials, {} fits, {wall:.1} s wall on {} threads ({:.2} s per material); \
         target {target:.0} s: {}",
        materials.len(),
        rows.len(),
        rayon::current_num_threads(),
        wall / materials.len().max(1) as f64,
        if wall <= target { "met" } else { "missed" }
    );
    Ok(())
}
