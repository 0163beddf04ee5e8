//! `gantry wavelet basis|compress`: the Common Wavelet Basis of a corpus (thesis §6.1–6.2) and
//! materials compressed onto it (`.wtree` files, loaded anywhere as `wavelet:<file.wtree>`);
//! the `wavelet` crate's jobs.

use anyhow::Result;
use clap::Subcommand;
use wavelet::{BasisJob, CompressJob};

/// Subcommands of `gantry wavelet`.
#[derive(Subcommand, Debug)]
pub enum WaveletCommand {
    /// Builds the Common Wavelet Basis (Haar, 256³) of the log RGB channels of a corpus.
    Basis(BasisJob),
    /// Compresses a material onto a basis (a `.wtree` file that `render` can use).
    Compress(CompressJob),
}

/// Runs a `gantry wavelet` subcommand.
pub fn run(cmd: WaveletCommand) -> Result<()> {
    match cmd {
        WaveletCommand::Basis(a) => println!("{}", a.run()?),
        WaveletCommand::Compress(a) => println!("{}", a.run()?),
    }
    Ok(())
}
