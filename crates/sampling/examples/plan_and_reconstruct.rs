//! Sparse acquisition in one page: learn a model from a training corpus, plan which values to
//! measure, simulate the measurement of a new material, reconstruct its table and score it.
//!
//! `cargo run --release -p sampling --example plan_and_reconstruct -- [method] [n] [target spec]`
//! (defaults `pca`, 60, `ggx:alpha=0.25,kd=0.15`). The training corpus is a family of analytic
//! materials on a 15 × 15 × 30 sub-grid of the MERL grid; `sampling::plan` and
//! `sampling::reconstruct` are what `gantry sample plan|reconstruct` call on measured corpora.

use brdf::Brdf;
use sampling::{measure_plan, metrics, GridTable, SampleGrid, TrainingSet};
use sampling::{Method, Model, PlanOptions};

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let mut args = std::env::args().skip(1);
    let method: Method = args.next().unwrap_or_else(|| "pca".into()).parse()?;
    let n: usize = args.next().map(|s| s.parse()).transpose()?.unwrap_or(60);
    let target_spec = args
        .next()
        .unwrap_or_else(|| "ggx:alpha=0.25,kd=0.15".into());

    let grid = SampleGrid::new(15, 15, 30)?;
    let mut training: Vec<Box<dyn Brdf>> = Vec::new();
    for alpha in [0.08, 0.15, 0.3, 0.5] {
        for kd in [0.05, 0.2, 0.4] {
            let spec = format!("ggx:alpha={alpha},kd={kd}");
            training.push(Box::new(brdf::load(&spec)?));
        }
    }
    let set = TrainingSet::from_brdfs(&training, grid)?;
    let model = match method {
        Method::Pca => Model::LogPca(sampling::LogPcaModel::fit(&set, 8, 0.01)?),
        _ => Model::LinComb(set),
    };
    let plan = sampling::plan(method, n, &model, PlanOptions::default())?;
    println!("{method:?}: {} planned values on a {grid:?}", plan.len());

    let target = brdf::load(&target_spec)?;
    let measured = measure_plan(&plan, &target, 0.01, 1)?; // 1 % noise, seeded
    let table = sampling::reconstruct(method, &measured, &model)?;
    let reference = GridTable::tabulate(&target, grid);
    println!(
        "{target_spec}: relative log RMS error {:.4}, relative sphere-image error {:.4}",
        metrics::log_rms_relative(&reference, &table)?,
        metrics::image_rms_relative(&reference, &table, 64)?
    );
    Ok(())
}
