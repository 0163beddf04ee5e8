//! Study of the linear-combination method (§6.5): where its error comes from.
//!
//! `cargo run --release -p sampling --example lincomb_study -- [--step H,D,P] [--n N]
//!  [--proposals P] [--sphere S] [--per-material]`
//!
//! Trains on the 96 shared MERL materials and tests on the 8 Nielsen materials. Prints the
//! mean errors (log % / sphere %) of:
//! * the least-squares projection of each test material onto the training span using every
//!   measurable row (the floor of any row selection), unweighted and with every equation
//!   divided by the corpus mean of its row (relative error);
//! * the three linear-combination methods of `sampling::methods` (`lincomb`, the thesis's;
//!   `lincomb-whitened`; `lincomb-relative`) through plan → measure → reconstruct, for each
//!   `n` of `--n` (default 100,200,400,800,1500).
//!
//! Besides the two metrics of docs/sampling.md it prints the linear relative RMS error
//! `‖f̂ − f‖ / ‖f‖` over the measurable rows, the quantity the unweighted least-squares fit
//! minimises.

use std::time::Instant;

use nalgebra::{DMatrix, DVector};
use rayon::prelude::*;
use sampling::measure_plan;
use sampling::metrics::{image_rms_relative, log_rms_relative};
use sampling::GridTable;
use sampling::{measurable_rows, TrainingSet};
use sampling::{plan_from_rows, reconstruct, Method, Model};
use sampling::{RowWeights, SwapSearch};

mod common;

use common::{arg, grid_arg, load_benchmark, Error};

/// Least squares over every measurable row, each equation scaled by its weight.
fn projection(t: &TrainingSet, b: &GridTable, w: &RowWeights) -> Vec<f64> {
    let d = t.dim();
    let nm = t.len();
    let mask = measurable_rows(&t.grid);
    let (g, h) = (0..d)
        .into_par_iter()
        .filter(|&r| mask[r] && b.values[r].is_finite() && b.values[r] >= 0.0)
        .fold(
            || (DMatrix::<f64>::zeros(nm, nm), DVector::<f64>::zeros(nm)),
            |(mut g, mut h), r| {
                let y = DVector::from_fn(nm, |m, _| f64::from(t.values[m * d + r]) * w.get(r));
                g.ger(1.0, &y, &y, 1.0);
                h.axpy(b.values[r] * w.get(r), &y, 1.0);
                (g, h)
            },
        )
        .reduce(
            || (DMatrix::<f64>::zeros(nm, nm), DVector::<f64>::zeros(nm)),
            |a, b| (a.0 + b.0, a.1 + b.1),
        );
    let svd = g.svd(true, true);
    let eps = svd.singular_values.max() * 1e-13;
    svd.solve(&h, eps).expect("svd").iter().copied().collect()
}

/// `‖est − ref‖ / ‖ref‖` in linear values over the measurable rows.
fn linear_rms_relative(reference: &GridTable, estimate: &GridTable, mask: &[bool]) -> f64 {
    let (mut num, mut den) = (0.0, 0.0);
    for (r, (&y, &e)) in reference.values.iter().zip(&estimate.values).enumerate() {
        if mask[r] && y.is_finite() && y >= 0.0 {
            num += (e - y) * (e - y);
            den += y * y;
        }
    }
    (num / den).sqrt()
}

fn main() -> Result<(), Error> {
    let args: Vec<String> = std::env::args().collect();
    let grid = grid_arg(&args)?;
    let ns: Vec<usize> = arg(&args, "--n", "100,200,400,800,1500".to_string())
        .split(',')
        .map(|v| v.parse())
        .collect::<Result<_, _>>()?;
    let proposals: usize = arg(&args, "--proposals", 2000);
    let sphere: usize = arg(&args, "--sphere", 64);
    let per_material = args.iter().any(|a| a == "--per-material");
    let common::Benchmark {
        training,
        test,
        refs,
        decode_seconds,
    } = load_benchmark(grid)?;
    println!("# decode {:.1} s", decode_seconds);
    let mask = measurable_rows(&grid);
    let names: Vec<String> = test.iter().map(|m| m.material_name().to_string()).collect();
    let score = |label: &str, estimate: &dyn Fn(usize) -> GridTable| {
        let (mut a, mut b, mut c) = (0.0, 0.0, 0.0);
        for (i, r) in refs.iter().enumerate() {
            let est = estimate(i);
            let el = log_rms_relative(r, &est).expect("log");
            let es = image_rms_relative(r, &est, sphere).expect("sphere");
            let ec = linear_rms_relative(r, &est, &mask);
            if per_material {
                println!(
                    "  {}: log {:.2} % sphere {:.2} % linear {:.2} %",
                    names[i],
                    100.0 * el,
                    100.0 * es,
                    100.0 * ec
                );
            }
            a += el;
            b += es;
            c += ec;
        }
        let k = refs.len() as f64;
        println!(
            "{label}: log {:.2} % sphere {:.2} % linear {:.2} %",
            100.0 * a / k,
            100.0 * b / k,
            100.0 * c / k
        );
    };
    let relative = RowWeights::relative(&training);
    for (label, w) in [("absolute", &RowWeights::Unit), ("relative", &relative)] {
        score(&format!("projection (all rows), {label}"), &|i| {
            let c = projection(&training, &refs[i], w);
            sampling::combine(&training, &c).expect("combine")
        });
    }
    let model = Model::LinComb(training);
    let training = model.lincomb_training().expect("built above");
    for name in ["lincomb", "lincomb-whitened", "lincomb-relative"] {
        let method: Method = name.parse()?;
        let Method::LinComb(options) = method else {
            unreachable!("a lincomb name")
        };
        for &n in &ns {
            let t = Instant::now();
            let sel = sampling::select_rows_weighted(
                training,
                n,
                SwapSearch {
                    proposals,
                    seed: 7,
                    basis: options.basis,
                },
                &options.weights(training),
            )?;
            let secs = t.elapsed().as_secs_f64();
            let p = plan_from_rows(&training.grid, &sel.rows);
            let label = format!(
                "{name} n={n}: ratio {:.2e} -> {:.2e}, {} swaps, {secs:.1} s",
                sel.initial_ratio, sel.final_ratio, sel.accepted
            );
            score(&label, &|i| {
                let m = measure_plan(&p, &test[i], 0.0, 1000 + i as u64).expect("plan");
                reconstruct(method, &m, &model).expect("reconstruct")
            });
        }
    }
    Ok(())
}
