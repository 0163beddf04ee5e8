//! `gantry wavelet basis|compress`: the Common Wavelet Basis of a corpus (thesis §6.1–6.2) and
//! materials compressed onto it (`.wtree` files, loaded anywhere as `wavelet:<file.wtree>`).
//! The format and the material live in `wavelet::material`.

use anyhow::{Context, Result};
use clap::{Args, Subcommand};
use std::path::PathBuf;
use wavelet::cwb::CommonBasis;
use wavelet::material::{build_basis, CompressedMaterial};

/// Subcommands of `gantry wavelet`.
#[derive(Subcommand, Debug)]
pub enum WaveletCommand {
    /// Builds the Common Wavelet Basis (Haar, 256³) of the log RGB channels of a corpus.
    Basis(BasisArgs),
    /// Compresses a material onto a basis (a `.wtree` file that `render` can use).
    Compress(CompressArgs),
}

/// Arguments of `gantry wavelet basis`.
#[derive(Args, Debug)]
pub struct BasisArgs {
    #[arg(long, num_args = 1.., required = true, help = crate::CORPUS_HELP)]
    corpus: Vec<String>,
    /// Relative L2 error kept per log channel.
    #[arg(long, default_value_t = 0.005)]
    target: f64,
    /// Output basis file.
    #[arg(long)]
    out: PathBuf,
}

/// Arguments of `gantry wavelet compress`.
#[derive(Args, Debug)]
pub struct CompressArgs {
    /// Material spec.
    spec: String,
    /// Basis file from `gantry wavelet basis`.
    #[arg(long)]
    basis: PathBuf,
    /// Output `.wtree` file.
    #[arg(long)]
    out: PathBuf,
}

/// Runs a `gantry wavelet` subcommand.
pub fn run(cmd: WaveletCommand) -> Result<()> {
    match cmd {
        WaveletCommand::Basis(a) => {
            let tables: Vec<brdf::MerlTable> = brdf::corpus::load_tables(&a.corpus)
                .context("cannot load the corpus")?
                .into_iter()
                .map(|(_, t)| t)
                .collect();
            let basis = build_basis(&tables, a.target)?;
            if let Some(dir) = a.out.parent().filter(|d| !d.as_os_str().is_empty()) {
                std::fs::create_dir_all(dir)?;
            }
            basis.write(&a.out)?;
            println!(
                "wrote {}: {} coefficients ({:.2}% of a table) for {} materials",
                a.out.display(),
                basis.len(),
                100.0 * basis.fraction_of_table(),
                tables.len()
            );
        }
        WaveletCommand::Compress(a) => {
            let basis = CommonBasis::read(&a.basis)
                .with_context(|| format!("cannot read basis {}", a.basis.display()))?;
            let table = brdf::spec::load(&a.spec)
                .with_context(|| format!("cannot load material '{}'", a.spec))?
                .tabulate();
            let n = basis.len();
            CompressedMaterial::compress(basis, &table)?.write(&a.out)?;
            println!("wrote {} ({n} coefficients per channel)", a.out.display());
        }
    }
    Ok(())
}
