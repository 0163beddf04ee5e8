//! `gantry traits fit|score|path` and `gantry edit`: trait vectors, scores, process paths and
//! physically valid edits (the `traits` crate).

use anyhow::{bail, Context, Result};
use clap::{Args, Subcommand};
use std::path::PathBuf;
use traits::navigate::{path_points, Navigator, NavigatorOptions, PathKind, Space, TraitSet};
use traits::study::SetFit;
use traits::{FitOptions, LabelSet, Method, RatingSet};

/// Subcommands of `gantry traits`.
#[derive(Subcommand, Debug)]
pub enum TraitsCommand {
    /// Fit trait vectors from a label file (binary) or rating file (ridge) on a model.
    Fit(FitArgs),
    /// Print the trait scores of materials as CSV.
    Score(ScoreArgs),
    /// Interpolate along a path of materials and write the valid tables.
    Path(PathArgs),
}

/// Arguments of `gantry traits fit`.
#[derive(Args, Debug)]
pub struct FitArgs {
    /// Label CSV (1 / -1 / empty) for mean, fisher, svm; rating CSV ([0, 1]) for ridge.
    #[arg(long)]
    labels: PathBuf,
    /// Model file (`gantry model build`).
    #[arg(long)]
    model: PathBuf,
    /// linear or chart.
    #[arg(long, default_value = "linear")]
    space: Space,
    /// mean, fisher, svm or ridge.
    #[arg(long, default_value = "svm")]
    method: Method,
    /// PCA coordinates of the linear space.
    #[arg(long, default_value_t = traits::navigate::LINEAR_DIM)]
    dim: usize,
    /// Skip the leave-one-out agreement.
    #[arg(long)]
    no_cv: bool,
    /// Output JSON.
    #[arg(long)]
    out: PathBuf,
}

/// Arguments of `gantry traits score`.
#[derive(Args, Debug)]
pub struct ScoreArgs {
    /// Material specs (corpus names are looked up in the model directly).
    #[arg(required = true)]
    specs: Vec<String>,
    /// Trait set JSON.
    #[arg(long)]
    traits: PathBuf,
    /// Model file.
    #[arg(long)]
    model: PathBuf,
}

/// Arguments of `gantry traits path`.
#[derive(Args, Debug)]
pub struct PathArgs {
    /// Two or more material specs along the path.
    #[arg(required = true, num_args = 2..)]
    specs: Vec<String>,
    /// Model file.
    #[arg(long)]
    model: PathBuf,
    /// linear or chart.
    #[arg(long, default_value = "chart")]
    space: Space,
    /// Points along the path.
    #[arg(long, default_value_t = 8)]
    steps: usize,
    /// Least-squares line instead of the piecewise path.
    #[arg(long)]
    least_squares: bool,
    /// Output directory (step-NN.binary and path.csv).
    #[arg(long)]
    out: PathBuf,
}

/// Arguments of `gantry edit`.
#[derive(Args, Debug)]
pub struct EditArgs {
    /// Material spec to start from.
    spec: String,
    /// Trait set JSON.
    #[arg(long)]
    traits: PathBuf,
    /// Model file.
    #[arg(long)]
    model: PathBuf,
    /// `trait=amount` (trait units: 1 = from the average material without it to the average
    /// with it). Repeatable; all are applied as one move.
    #[arg(long = "add", required = true)]
    add: Vec<String>,
    /// Also keep the point inside the convex hull of the corpus.
    #[arg(long)]
    hull: bool,
    /// Output MERL .binary file.
    #[arg(long)]
    out: PathBuf,
}

fn load_model(p: &PathBuf) -> Result<reduce::model::Model> {
    reduce::model::Model::load(p).with_context(|| format!("cannot load model {}", p.display()))
}

/// Coordinates of a spec: a corpus name directly, anything else projected.
fn coords_of(nav_emb: &traits::Embedding, spec: &str) -> Result<Vec<f64>> {
    let name = spec.strip_prefix("merl:").unwrap_or(spec);
    if nav_emb.model.names.iter().any(|n| n == name) {
        return Ok(nav_emb.of_name(name)?);
    }
    let table = brdf::spec::load(spec)
        .with_context(|| format!("cannot load {spec}"))?
        .tabulate();
    Ok(nav_emb.project_values(&table.values())?)
}

/// Runs a `gantry traits` subcommand.
pub fn run(cmd: TraitsCommand) -> Result<()> {
    match cmd {
        TraitsCommand::Fit(a) => {
            let model = load_model(&a.model)?;
            let emb = traits::Embedding::new(&model, a.space, a.dim)?;
            let coords = emb.corpus()?;
            let fit = SetFit {
                coords: &coords,
                names: &model.names,
                space: a.space,
                options: FitOptions::default(),
                cross_validate: !a.no_cv,
            };
            let set = if a.method == Method::Ridge {
                fit.ratings(&RatingSet::load(&a.labels)?)?
            } else {
                fit.binary(&LabelSet::load(&a.labels)?, a.method)?
            };
            set.save(&a.out)?;
            println!("trait,cross_validated");
            for t in &set.traits {
                println!(
                    "{},{}",
                    t.name,
                    t.cross_validated
                        .map_or(String::new(), |v| format!("{v:.3}"))
                );
            }
            eprintln!("wrote {}", a.out.display());
        }
        TraitsCommand::Score(a) => {
            let model = load_model(&a.model)?;
            let set = TraitSet::load(&a.traits)?;
            let emb = traits::Embedding::new(&model, set.space, set.dim)?;
            let names: Vec<&str> = set.traits.iter().map(|t| t.name.as_str()).collect();
            println!("material,{}", names.join(","));
            for s in &a.specs {
                let x = coords_of(&emb, s)?;
                let scores: Vec<String> = set
                    .traits
                    .iter()
                    .map(|t| format!("{:.4}", t.direction.score(&x)))
                    .collect();
                println!("{s},{}", scores.join(","));
            }
        }
        TraitsCommand::Path(a) => {
            let model = load_model(&a.model)?;
            let nav = Navigator::new(&model, a.space, NavigatorOptions::default())?;
            let pts = a
                .specs
                .iter()
                .map(|s| coords_of(&nav.embedding, s))
                .collect::<Result<Vec<_>>>()?;
            let kind = if a.least_squares {
                PathKind::LeastSquares
            } else {
                PathKind::Piecewise
            };
            std::fs::create_dir_all(&a.out)
                .with_context(|| format!("cannot create {}", a.out.display()))?;
            let mut csv = String::from("step,file,valid,failed,max_albedo\n");
            for (i, x) in path_points(&pts, a.steps, kind)?.iter().enumerate() {
                let s = nav.state(x)?;
                let fails = nav.failures(&s)?;
                let (table, report) = nav.table(&s)?;
                let file = format!("step-{i:02}.binary");
                let ok = fails.is_empty() && report.is_valid();
                if ok {
                    brdf::merl::write(a.out.join(&file), &table)?;
                }
                csv.push_str(&format!(
                    "{i},{},{ok},{:?},{:.4}\n",
                    if ok { file.as_str() } else { "" },
                    fails,
                    report.max_albedo.0
                ));
                println!(
                    "step {i}: {}",
                    if ok {
                        "valid, written"
                    } else {
                        "invalid, not written"
                    }
                );
            }
            brdf::write_atomic(&a.out.join("path.csv"), csv.as_bytes())?;
        }
    }
    Ok(())
}

/// Runs `gantry edit`.
pub fn edit(a: EditArgs) -> Result<()> {
    let model = load_model(&a.model)?;
    let set = TraitSet::load(&a.traits)?;
    let opts = NavigatorOptions {
        convex_hull: a.hull,
        linear_dim: set.dim,
        ..Default::default()
    };
    let nav = Navigator::new(&model, set.space, opts)?;
    let x = coords_of(&nav.embedding, &a.spec)?;
    let mut edits = Vec::new();
    for kv in &a.add {
        let Some((k, v)) = kv.split_once('=') else {
            bail!("--add {kv:?}: expected trait=amount");
        };
        let amount: f64 = v.parse().with_context(|| format!("--add {kv:?}"))?;
        edits.push((set.get(k)?, amount));
    }
    let out = nav.edit_many(&x, &edits)?;
    let frac = if out.requested != 0.0 {
        out.applied / out.requested
    } else {
        1.0
    };
    println!(
        "moved {:.1} % of the requested edit{}",
        100.0 * frac,
        out.stopped_by
            .map(|c| format!(", stopped at the border by {c}"))
            .unwrap_or_default()
    );
    println!("{}", serde_json::to_string_pretty(&out.report)?);
    for t in &set.traits {
        println!(
            "score {}: {:.3} -> {:.3}",
            t.name,
            t.direction.score(&x),
            t.direction.score(&out.coords)
        );
    }
    brdf::merl::write(&a.out, &out.table)?;
    eprintln!("wrote {}", a.out.display());
    Ok(())
}
