//! `gantry traits fit|score|path` and `gantry edit`: trait vectors, scores, process paths and
//! physically valid edits (the `traits` crate).

use anyhow::Result;
use clap::Subcommand;
use traits::{EditJob, FitJob, PathJob, ScoreJob};

/// Subcommands of `gantry traits`.
#[derive(Subcommand, Debug)]
pub enum TraitsCommand {
    /// Fit trait vectors from a label file (binary) or rating file (ridge) on a model.
    Fit(FitJob),
    /// Print the trait scores of materials as CSV.
    Score(ScoreJob),
    /// Interpolate along a path of materials and write the valid tables.
    Path(PathJob),
}

/// Runs a `gantry traits` subcommand.
pub fn run(cmd: TraitsCommand) -> Result<()> {
    match cmd {
        TraitsCommand::Fit(a) => {
            println!("{}", a.run()?);
            eprintln!("wrote {}", a.out.display());
        }
        TraitsCommand::Score(a) => println!("{}", a.run()?),
        TraitsCommand::Path(a) => println!("{}", a.run()?),
    }
    Ok(())
}

/// Runs `gantry edit`.
pub fn edit(a: EditJob) -> Result<()> {
    println!("{}", a.run()?);
    eprintln!("wrote {}", a.out.display());
    Ok(())
}
