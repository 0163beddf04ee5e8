//! `gantry corpus pack|synth|info|pca`: chunked Zarr corpus stores and the out-of-core PCA
//! (docs/corpus-store.md).

use anyhow::{bail, Result};
use clap::Subcommand;
use corpus_store::PackProgress;
use corpus_store::{InfoJob, PackJob, PcaJob, SynthJob};

use crate::progress::bar;

/// Subcommands of `gantry corpus`.
#[derive(Subcommand, Debug)]
pub enum CorpusCommand {
    /// Pack materials (NBRDF directories, .binary files, specs, stores) into a Zarr store
    /// (resumable: rerun the same command after an interruption).
    Pack(PackJob),
    /// Write a synthetic corpus of N physically valid materials made from measured ones.
    Synth(SynthJob),
    /// Summarise a store: materials, grid, layout, compression, completeness.
    Info(InfoJob),
    /// PCA of a store out of core, within a memory budget; writes a model file.
    Pca(PcaJob),
}

/// A progress bar over materials, as `pack` reports them.
fn pack_bar() -> (indicatif::ProgressBar, impl FnMut(PackProgress)) {
    let b = bar(
        0,
        "{elapsed_precise} [{bar:40}] {pos}/{len} materials ({per_sec}, eta {eta}) {msg}",
    );
    let shown = b.clone();
    (b, move |p: PackProgress| {
        shown.set_length(p.total as u64);
        shown.set_position(p.done as u64);
        if p.skipped > 0 {
            shown.set_message(format!("{} already on disk", p.skipped));
        }
    })
}

/// Runs a `gantry corpus` subcommand.
pub fn run(cmd: CorpusCommand) -> Result<()> {
    match cmd {
        CorpusCommand::Pack(a) => {
            let (b, mut progress) = pack_bar();
            let report = a.run(&mut progress)?;
            b.finish();
            println!("{report}");
        }
        CorpusCommand::Synth(a) => {
            let (b, mut progress) = pack_bar();
            let report = a.run(&mut progress)?;
            b.finish();
            println!("{report}");
        }
        CorpusCommand::Info(a) => {
            let b = bar(
                0,
                "verifying {bar:30} {pos}/{len} material blocks {elapsed}",
            );
            let report = a.run(&|done, all| {
                b.set_length(all as u64);
                b.set_position(done as u64)
            })?;
            b.finish_and_clear();
            println!("{report}");
            if !report.is_complete() {
                bail!(
                    "{}: {} faulty chunks; run `gantry corpus pack` (or `synth`) again with the same --out to re-pack them",
                    a.store.display(),
                    report.verification.as_ref().map_or(report.missing_chunks, |v| v.faults.len())
                );
            }
        }
        CorpusCommand::Pca(a) => println!("{}", a.run()?),
    }
    Ok(())
}
