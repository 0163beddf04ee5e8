//! `gantry sample model|plan|measure|reconstruct`: measuring a new material from few samples
//! (thesis ch. 6 and beyond).

use anyhow::{Context, Result};
use clap::{Args, Subcommand};
use sampling::methods::{self, Method, Model, PlanOptions};
use sampling::plan::{Measurements, Plan};
use std::path::PathBuf;

/// Subcommands of `gantry sample`.
#[derive(Subcommand, Debug)]
pub enum SampleCommand {
    /// Learn what a method needs (training tables, PCA basis, wavelet basis) from a corpus.
    Model(ModelArgs),
    /// Choose the points to measure: CSV with header theta_h,theta_d,phi_d,channel.
    Plan(PlanArgs),
    /// "Measure" a plan on a material (planar-sample gonioreflectometer model with noise).
    Measure(MeasureArgs),
    /// Reconstruct a full table from the measured values of a plan.
    Reconstruct(ReconstructArgs),
}

fn method(s: &str) -> Result<Method> {
    Ok(s.parse::<Method>()?)
}

/// Arguments of `gantry sample model`.
#[derive(Args, Debug)]
pub struct ModelArgs {
    /// Method: lincomb, lincomb-whitened, lincomb-relative, pca, pullpush, wavelet.
    #[arg(long)]
    method: String,
    #[arg(long, num_args = 1.., required = true, help = crate::CORPUS_HELP)]
    corpus: Vec<String>,
    /// Sub-grid strides over (θh, θd, φd) of the MERL grid.
    #[arg(long, num_args = 3, default_values_t = [1, 1, 1])]
    stride: Vec<usize>,
    /// Expected relative measurement noise (regularises the PCA fit).
    #[arg(long, default_value_t = 0.01)]
    noise: f64,
    /// Output model file.
    #[arg(long)]
    out: PathBuf,
}

/// Arguments of `gantry sample plan`.
#[derive(Args, Debug)]
pub struct PlanArgs {
    /// Method: lincomb, lincomb-whitened, lincomb-relative, pca, pullpush, wavelet.
    #[arg(long)]
    method: String,
    /// Number of values to measure. Wavelet, and pull-push with a wavelet model: 0 = one point per
    /// basis function, otherwise about n/3 points chosen coarse to fine, 3 channels per point.
    #[arg(long)]
    n: usize,
    /// Model file from `gantry sample model` (optional for pull-push: a uniform random plan on
    /// the full grid).
    #[arg(long)]
    model: Option<PathBuf>,
    /// Seed of the random choices.
    #[arg(long, default_value_t = 1)]
    seed: u64,
    /// Output plan CSV.
    #[arg(long)]
    out: PathBuf,
}

/// Arguments of `gantry sample measure`.
#[derive(Args, Debug)]
pub struct MeasureArgs {
    /// Material spec to measure.
    spec: String,
    /// Plan CSV.
    #[arg(long)]
    plan: PathBuf,
    /// Relative (log-normal) measurement noise.
    #[arg(long, default_value_t = 0.0)]
    noise: f64,
    /// Seed of the noise.
    #[arg(long, default_value_t = 1)]
    seed: u64,
    /// Output values CSV.
    #[arg(long)]
    out: PathBuf,
}

/// Arguments of `gantry sample reconstruct`.
#[derive(Args, Debug)]
pub struct ReconstructArgs {
    /// Method used for the plan (default: the one the model file was built for; pull-push
    /// without a model). A linear-combination model defaults to `lincomb`; a plan made with
    /// `lincomb-relative` should be reconstructed with it too, as it fits relative equations.
    #[arg(long)]
    method: Option<String>,
    /// Plan CSV (checked against the values).
    #[arg(long)]
    plan: PathBuf,
    /// Values CSV: the plan's columns plus `value` (BRDF, 1/sr).
    #[arg(long)]
    values: PathBuf,
    /// Model file (optional for pull-push).
    #[arg(long)]
    model: Option<PathBuf>,
    /// Output MERL .binary file.
    #[arg(long)]
    out: PathBuf,
}

/// The model of `path`, or for pull-push without one the full MERL grid.
fn load_model(path: Option<&std::path::Path>, m: Method) -> Result<Model> {
    match path {
        Some(p) => {
            sampling::model_file::load(p).with_context(|| format!("cannot load {}", p.display()))
        }
        None if m == Method::PullPush => Ok(Model::Grid(sampling::grid::SampleGrid::FULL)),
        None => anyhow::bail!("--model is required for this method"),
    }
}

/// Runs a `gantry sample` subcommand.
pub fn run(cmd: SampleCommand) -> Result<()> {
    match cmd {
        SampleCommand::Model(a) => {
            let m = method(&a.method)?;
            let [s0, s1, s2] = a.stride[..] else {
                anyhow::bail!("--stride takes three values");
            };
            let grid = sampling::grid::SampleGrid::new(s0, s1, s2)?;
            let training = sampling::training::TrainingSet::from_inputs(&a.corpus, grid)
                .with_context(|| format!("cannot load training corpus {}", a.corpus.join(" ")))?;
            let model = methods::build_model(m, training, a.noise)?;
            sampling::model_file::save(&model, &a.out)?;
            println!("wrote {}", a.out.display());
        }
        SampleCommand::Plan(a) => {
            let m = method(&a.method)?;
            let model = load_model(a.model.as_deref(), m)?;
            let plan = methods::plan(
                m,
                a.n,
                &model,
                PlanOptions {
                    seed: a.seed,
                    ..Default::default()
                },
            )?;
            plan.write_csv(&a.out)?;
            println!(
                "wrote {} ({} values to measure)",
                a.out.display(),
                plan.points.len()
            );
        }
        SampleCommand::Measure(a) => {
            let plan = Plan::read_csv(&a.plan)?;
            let material = brdf::spec::load(&a.spec)
                .with_context(|| format!("cannot load material '{}'", a.spec))?;
            let values = sampling::plan::measure_plan(&plan, &material, a.noise, a.seed)?;
            values.write_csv(&a.out)?;
            println!("wrote {}", a.out.display());
        }
        SampleCommand::Reconstruct(a) => {
            let plan = Plan::read_csv(&a.plan)?;
            let values = Measurements::read_csv(&a.values)?;
            if values.points != plan.points {
                anyhow::bail!(
                    "{}: the measured points are not those of the plan {}",
                    a.values.display(),
                    a.plan.display()
                );
            }
            let loaded = match &a.model {
                Some(p) => Some(
                    sampling::model_file::load(p)
                        .with_context(|| format!("cannot load {}", p.display()))?,
                ),
                None => None,
            };
            let m = match (&a.method, &loaded) {
                (Some(name), _) => method(name)?,
                (None, None) => Method::PullPush,
                (None, Some(Model::LinComb(_))) => Method::LinComb(Default::default()),
                (None, Some(Model::LogPca(_))) => Method::Pca,
                (None, Some(Model::Grid(_))) => Method::PullPush,
                (None, Some(Model::Wavelet(_))) => Method::Wavelet,
            };
            let model = match loaded {
                Some(model) => model,
                None => load_model(None, m)?,
            };
            let table = methods::reconstruct(m, &values, &model)?.to_merl()?;
            brdf::merl::write(&a.out, &table)?;
            println!("wrote {}", a.out.display());
        }
    }
    Ok(())
}
