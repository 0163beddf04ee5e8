//! `gantry model build|reconstruct|report`: linear and non-linear models of the space of BRDFs.

use anyhow::{Context, Result};
use clap::{Args, Subcommand};
use std::path::PathBuf;

/// Subcommands of `gantry model`.
#[derive(Subcommand, Debug)]
pub enum ModelCommand {
    /// Learn a PCA model (log space) and a chart from a corpus of measured BRDFs.
    Build(BuildArgs),
    /// Project a material onto the first K components and write the reconstruction.
    Reconstruct(ReconstructArgs),
    /// Write the eigenvalue and error curves (PNG plots and CSV) of a model.
    Report(ReportArgs),
}

/// Arguments of `gantry model build`.
#[derive(Args, Debug)]
pub struct BuildArgs {
    #[arg(long, num_args = 1.., required = true, help = crate::CORPUS_HELP)]
    corpus: Vec<String>,
    /// Output model file.
    #[arg(long)]
    out: PathBuf,
    /// Number of principal components kept.
    #[arg(long)]
    components: Option<usize>,
    /// Dimension of the chart (non-linear model); 0 disables charting.
    #[arg(long, default_value_t = reduce::model::DEFAULT_CHART_DIM)]
    chart_dim: usize,
}

/// Arguments of `gantry model reconstruct`.
#[derive(Args, Debug)]
pub struct ReconstructArgs {
    /// Material spec to project.
    spec: String,
    /// Model file.
    #[arg(long)]
    model: PathBuf,
    /// Number of components used.
    #[arg(long)]
    k: usize,
    /// Output MERL .binary file.
    #[arg(long)]
    out: PathBuf,
}

/// Arguments of `gantry model report`.
#[derive(Args, Debug)]
pub struct ReportArgs {
    /// Model file.
    model: PathBuf,
    /// Output directory for plots and CSV files.
    #[arg(long)]
    out: PathBuf,
}

/// Runs a `gantry model` subcommand.
pub fn run(cmd: ModelCommand) -> Result<()> {
    match cmd {
        ModelCommand::Build(a) => {
            let corpus =
                reduce::corpus::Corpus::load(&a.corpus).context("cannot load the corpus")?;
            let k = a
                .components
                .unwrap_or(reduce::model::DEFAULT_COMPONENTS)
                .min(corpus.len().saturating_sub(1).max(1));
            // Charting needs a neighbourhood for every point: skip it for tiny corpora.
            let chart = (a.chart_dim > 0 && corpus.len() > a.chart_dim + 2).then_some(a.chart_dim);
            let model = reduce::model::build_model(&corpus, k, chart, Some(45.min(k)))?;
            if let Some(dir) = a.out.parent().filter(|d| !d.as_os_str().is_empty()) {
                std::fs::create_dir_all(dir)
                    .with_context(|| format!("cannot create {}", dir.display()))?;
            }
            model
                .save(&a.out)
                .with_context(|| format!("cannot write {}", a.out.display()))?;
            println!(
                "wrote {} ({} materials, {} components{})",
                a.out.display(),
                corpus.len(),
                k,
                chart
                    .map(|d| format!(", chart of dimension {d}"))
                    .unwrap_or_default()
            );
        }
        ModelCommand::Reconstruct(a) => {
            let model = reduce::model::Model::load(&a.model)
                .with_context(|| format!("cannot load model {}", a.model.display()))?;
            if let Some(dir) = a.out.parent().filter(|d| !d.as_os_str().is_empty()) {
                std::fs::create_dir_all(dir)
                    .with_context(|| format!("cannot create {}", dir.display()))?;
            }
            let err = model.reconstruct_spec_to_file(&a.spec, a.k, &a.out)?;
            println!(
                "wrote {}: k = {}, relative error {:.4}, RMS log error {:.4}",
                a.out.display(),
                err.k,
                err.relative,
                err.rms_log
            );
        }
        ModelCommand::Report(a) => {
            let model = reduce::model::Model::load(&a.model)
                .with_context(|| format!("cannot load model {}", a.model.display()))?;
            reduce::report::write_report(&model, &a.out)?;
            println!("wrote the report to {}", a.out.display());
        }
    }
    Ok(())
}
