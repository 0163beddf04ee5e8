//! `gantry model build|reconstruct|report|evaluate`: linear and non-linear models of the space of BRDFs
//! (the `reduce` crate's jobs).

use anyhow::Result;
use clap::Subcommand;
use reduce::{BuildJob, EvaluateJob, ReconstructJob, ReportJob};

/// Subcommands of `gantry model`.
#[derive(Subcommand, Debug)]
pub enum ModelCommand {
    /// Learn a PCA model (log space) and a chart from a corpus of measured BRDFs.
    Build(BuildJob),
    /// Project a material onto the first K components and write the reconstruction.
    Reconstruct(ReconstructJob),
    /// Write the eigenvalue and error curves (PNG plots and CSV) of a model.
    Report(ReportJob),
    /// Measure how well models describe materials they were not built from (leave-one-out
    /// over the corpus, and materials outside it).
    Evaluate(EvaluateJob),
}

/// Runs a `gantry model` subcommand.
pub fn run(cmd: ModelCommand) -> Result<()> {
    match cmd {
        ModelCommand::Build(a) => println!("{}", a.run()?),
        ModelCommand::Reconstruct(a) => println!("{}", a.run()?),
        ModelCommand::Report(a) => println!("{}", a.run()?),
        ModelCommand::Evaluate(a) => println!("{}", a.run()?),
    }
    Ok(())
}
