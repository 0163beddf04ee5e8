//! `gantry fit`: fit an analytic model to a material, or run the model comparison on a corpus.
//! All the work is in the `fit` crate.

use anyhow::{bail, Context, Result};
use clap::Args;
use fit::study::{markdown_summary, study_corpus, write_csv, StudyOptions};
use fit::{EvalRows, FitData, FitOptions, ModelKind, Objective, Subset};
use std::path::PathBuf;

#[derive(Args, Debug)]
pub struct FitArgs {
    /// Material spec to fit (e.g. merl:nickel, a .binary file).
    pub spec: Option<String>,
    /// Model: lambert, oren-nayar, blinn, phong, ward, lafortune, lafortune-rgb (the thesis's
    /// per-channel form), cook-torrance, ggx,
    /// ashikhmin-shirley (with --corpus: a comma-separated list or `all`).
    #[arg(long, alias = "models", default_value = "ggx")]
    pub model: String,
    /// Specular lobes (2 for lafortune, cook-torrance, ggx).
    #[arg(long, default_value_t = 1)]
    pub lobes: usize,
    /// Objective: log (thesis §3.7), ngan (cosine-weighted L2), sphere (rendered sphere).
    #[arg(long, default_value = "log")]
    pub objective: String,
    /// Fit on this many seeded random bins instead of every valid bin (the thesis used 2000).
    #[arg(long)]
    pub bins: Option<usize>,
    /// Number of starts of the multi-start.
    #[arg(long, default_value_t = 4)]
    pub starts: usize,
    /// Print the result as JSON.
    #[arg(long)]
    pub json: bool,
    /// Run the study on every material of a corpus: material specs, folders of neural-BRDF
    /// weights and/or .binary files, or corpus stores (see `gantry forms`).
    #[arg(long, num_args = 1..)]
    pub corpus: Vec<String>,
    /// Study CSV output.
    #[arg(long, default_value = "study.csv")]
    pub out: PathBuf,
}

pub fn run(a: FitArgs) -> Result<()> {
    match (&a.spec, a.corpus.is_empty()) {
        (Some(spec), true) => single(&a, spec),
        (None, false) => corpus(&a, &a.corpus),
        _ => bail!("give either a material spec or --corpus INPUTS"),
    }
}

fn single(a: &FitArgs, spec: &str) -> Result<()> {
    let kind = ModelKind::parse(&a.model, a.lobes)?;
    let objective = Objective::parse(&a.objective)?;
    let table = brdf::spec::load(spec)?.tabulate();
    let data = FitData::new(&table)?;
    let options = FitOptions {
        objective,
        subset: a
            .bins
            .map_or(Subset::All, |bins| Subset::Random { bins, seed: 7 }),
        starts: a.starts,
        ..FitOptions::default()
    };
    let r = fit::fit(kind, &data, &options)?;
    let errors = EvalRows::new(&data)?.errors(&r.model);
    if a.json {
        let v = serde_json::json!({
            "material": spec,
            "model": kind.name(),
            "objective": objective.name(),
            "parameters": r.model.named().into_iter().collect::<std::collections::BTreeMap<_, _>>(),
            "fit_error": r.fit_error,
            "errors": errors,
            "converged": r.converged,
            "best_start": r.best_start,
            "starts": r.starts,
            "rows": r.rows,
            "exclusions": data.exclusions,
            "spec": r.spec(),
        });
        println!("{}", serde_json::to_string_pretty(&v)?);
        return Ok(());
    }
    println!(
        "{spec}: {} fitted with the {} objective on {} rows ({} valid bins, {} missing, {} non-finite)",
        kind.name(),
        objective.name(),
        r.rows,
        data.exclusions.valid,
        data.exclusions.missing,
        data.exclusions.non_finite
    );
    for (k, v) in r.model.named() {
        println!("  {k:<10} {v:.6}");
    }
    println!(
        "errors on every valid bin: log {:.2} %, ngan {:.2} %, sphere {:.2} %",
        100.0 * errors.log,
        100.0 * errors.ngan,
        100.0 * errors.sphere
    );
    println!(
        "converged: {}, best start: {} of {}",
        r.converged,
        r.best_start,
        r.starts.len()
    );
    println!("{}", r.spec());
    Ok(())
}

fn corpus(a: &FitArgs, inputs: &[String]) -> Result<()> {
    let mut options = StudyOptions::default();
    if a.model != "all" {
        options.models = a
            .model
            .split(',')
            .map(|m| ModelKind::parse(m.trim(), a.lobes))
            .collect::<fit::Result<_>>()?;
    }
    options.fit.starts = a.starts;
    if let Some(bins) = a.bins {
        options.fit.subset = Subset::Random { bins, seed: 7 };
    }
    let sources = brdf::corpus::sources(inputs)
        .with_context(|| format!("cannot read the corpus {}", inputs.join(" ")))?;
    let names: Vec<String> = sources.iter().map(|s| s.name()).collect();
    if names.is_empty() {
        bail!("no materials in {}", inputs.join(" "));
    }
    let bar = indicatif::ProgressBar::new(names.len() as u64);
    bar.set_style(
        indicatif::ProgressStyle::with_template("{bar:40} {pos}/{len} materials, ETA {eta} {msg}")
            .unwrap_or_else(|_| indicatif::ProgressStyle::default_bar()),
    );
    let rows = study_corpus(
        &names,
        |i| -> anyhow::Result<brdf::MerlTable> {
            sources[i]
                .table()
                .with_context(|| format!("loading {}", names[i]))
        },
        &options,
        |k, rows| {
            write_csv(rows, &a.out)?;
            bar.set_message(names[k - 1].clone());
            bar.set_position(k as u64);
            Ok(())
        },
    )?;
    bar.finish_and_clear();
    println!("{} fits written to {}", rows.len(), a.out.display());
    println!("{}", markdown_summary(&rows));
    Ok(())
}
