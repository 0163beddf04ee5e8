//! `gantry fit`: fit an analytic model to a material, or run the model comparison on a corpus
//! (the `fit` crate's job).

use anyhow::Result;
use fit::FitJob;

use crate::progress::bar;

/// Runs `gantry fit`.
pub fn run(job: FitJob) -> Result<()> {
    let materials = bar(0, "{bar:40} {pos}/{len} materials, ETA {eta} {msg}");
    let report = job.run(&mut |done, of, name| {
        materials.set_length(of as u64);
        materials.set_position(done as u64);
        materials.set_message(name.to_string());
    })?;
    materials.finish_and_clear();
    if job.json {
        println!("{}", serde_json::to_string_pretty(&report)?);
    } else {
        println!("{report}");
    }
    Ok(())
}
