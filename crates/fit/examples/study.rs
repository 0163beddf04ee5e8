//! The model comparison across the corpus: every shared MERL and Nielsen material × every model
//! × the three objectives. Writes the CSV and prints the markdown summary and the wall time.
//!
//! ```text
//! cargo run --release -p fit --example study -- [out.csv] [max_materials]
//! ```
//! Fits use 2,000 seeded random bins per material (the thesis's 6,000 values), 3 starts;
//! reported log and Ngan errors use 100,000 seeded random valid bins, the sphere error every
//! lit pixel. `RAYON_NUM_THREADS` sets the cores used.

use fit::{markdown_summary, study_corpus, write_csv, StudyOptions};
use std::path::PathBuf;
use std::time::Instant;

fn main() -> Result<(), Box<dyn std::error::Error + Send + Sync>> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let out = PathBuf::from(args.first().map_or("study.csv", String::as_str));
    let max: usize = args.get(1).map_or(Ok(usize::MAX), |s| s.parse())?;
    let mut materials =
        brdf::nbrdf::shared_materials().map_err(|e| format!("{e} (set BRDF_DATA_DIR)"))?;
    materials.truncate(max);
    let options = StudyOptions::default();
    let t = Instant::now();
    let labels: Vec<String> = materials
        .iter()
        .map(|(set, _, name)| format!("{set}:{name}"))
        .collect();
    let rows = study_corpus(
        &labels,
        |i| -> fit::Result<_> { Ok(brdf::nbrdf::shared_table(&materials[i])?) },
        &options,
        |k, rows| {
            // Written after every material, so an interrupted run keeps what it has done.
            write_csv(rows, &out)?;
            eprintln!(
                "[{k}/{}] {} ({:.0} s)",
                materials.len(),
                labels[k - 1],
                t.elapsed().as_secs_f64()
            );
            Ok(())
        },
    )?;
    write_csv(&rows, &out)?;
    println!(
        "{} materials x {} models x {} objectives = {} fits in {:.1} s on {} threads",
        materials.len(),
        options.models.len(),
        options.objectives.len(),
        rows.len(),
        t.elapsed().as_secs_f64(),
        rayon::current_num_threads()
    );
    println!("{}", markdown_summary(&rows));
    Ok(())
}
