//! Fits one model to one material and prints the parameters, the errors and the spec.
//!
//! ```text
//! cargo run --release -p fit --example fit_material -- merl:yellow-paint lafortune [log|ngan|sphere] [bins] [starts] [patience]
//! ```
//! `bins` = 0 (the default) fits on every valid bin; otherwise on that many seeded random bins.
//! `starts` and `patience` override [`FitOptions`]'s (a dense multi-start search: many starts,
//! high patience).

use fit::{fit, EvalRows, FitData, FitOptions, ModelKind, Objective, Subset};
use std::time::Instant;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let spec = args.first().map_or("merl:yellow-paint", String::as_str);
    let model = ModelKind::parse(args.get(1).map_or("lafortune", String::as_str), 1)?;
    let objective = Objective::parse(args.get(2).map_or("log", String::as_str))?;
    let bins: usize = args.get(3).map_or(Ok(0), |s| s.parse())?;
    let defaults = FitOptions::default();
    let starts: usize = args.get(4).map_or(Ok(defaults.starts), |s| s.parse())?;
    let patience: usize = args.get(5).map_or(Ok(defaults.patience), |s| s.parse())?;
    let t = Instant::now();
    let table = brdf::load(spec)?.tabulate();
    let data = FitData::new(&table)?;
    let eval = EvalRows::new(&data)?;
    println!(
        "{spec}: {:?} (prepared in {:.2?})",
        data.exclusions,
        t.elapsed()
    );
    let options = FitOptions {
        objective,
        subset: if bins == 0 {
            Subset::All
        } else {
            Subset::Random { bins, seed: 7 }
        },
        starts,
        patience,
        ..defaults
    };
    let t = Instant::now();
    let r = fit(model, &data, &options)?;
    let e = eval.errors(&r.model);
    println!(
        "{} on {} rows, {:.2?}: fit error {:.4}, converged {}, best start {}",
        model.name(),
        r.rows,
        t.elapsed(),
        r.fit_error,
        r.converged,
        r.best_start
    );
    for s in &r.starts {
        println!(
            "  start: error {:.4} after {} evaluations ({})",
            s.error, s.evaluations, s.termination
        );
    }
    for (k, v) in r.model.named() {
        println!("  {k} = {v:.6}");
    }
    println!(
        "errors on all valid bins: log {:.2} %, ngan {:.2} %, sphere {:.2} %",
        100.0 * e.log,
        100.0 * e.ngan,
        100.0 * e.sphere
    );
    println!("{}", r.spec());
    Ok(())
}
