//! `gantry recover`: a material from photographs of an object of known shape and lighting
//! (the `recover` crate's job).

use anyhow::Result;
use recover::RecoverJob;

/// Runs `gantry recover`.
pub fn run(job: RecoverJob) -> Result<()> {
    println!("{}", job.run()?);
    Ok(())
}
