//! Measure a material on the simulated rig with the library's job, showing progress, then read
//! the table back and compare it with the material it measured.
//!
//! ```sh
//! cargo run --release -p acquire --example measure -- [MATERIAL [POSITIONS [SCALE]]]
//! cargo run --release -p acquire --example measure -- merl:blue-acrylic 330 0.5
//! ```
//!
//! Run it twice with the same output directory: the second run resumes from the checkpoints.

use acquire::{
    CalibrationSource, JobSpec, Outcome, Progress, RunOptions, SimSetup, Stage, Station,
};
use std::sync::Arc;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let material = args
        .first()
        .map_or("ggx:alpha=0.2,kd=0.2/0.1/0.05,ks=0.04", |s| s);
    let positions: usize = args.get(1).map_or(Ok(33), |s| s.parse())?;
    let scale: f64 = args.get(2).map_or(Ok(0.25), |s| s.parse())?;

    // What is measured: with the station, this determines the result (stored as DIR/job.json).
    let spec = JobSpec::new(material, positions);
    // The devices: here the simulated rig at sensor scale `scale`; on hardware,
    // Station::from_rig_file.
    let mut station = Station::simulated(&spec, &SimSetup::with_scale(scale))?;
    // How the job runs: calibrate the simulated rig first, resume if interrupted, and report.
    let options = RunOptions {
        calibration: CalibrationSource::Calibrate,
        resume: true,
        progress: Some(Arc::new(|p: &Progress| {
            if p.stage == Stage::Positions && p.done.is_multiple_of(10) {
                eprintln!("position {}/{}", p.done, p.total);
            }
        })),
        ..RunOptions::default()
    };
    let dir = std::path::Path::new("out/measure-example");
    match acquire::run(&mut station, &spec, &options, dir)? {
        Outcome::Finished(done) => {
            let r = &done.report;
            println!(
                "{} positions, {:.1} M samples, coverage {:.1}%, simulated capture clock {:.2} h",
                r.positions,
                r.samples_total as f64 / 1e6,
                100.0 * r.coverage,
                r.simulated_capture_hours.unwrap_or(0.0)
            );
            // The table is a MERL .binary file that every other part of the toolkit reads.
            let measured = brdf::merl::read(dir.join("brdf.binary"))?;
            let truth = brdf::load(material)?.tabulate();
            let e = acquire::table_error(&measured, &truth);
            println!(
                "table vs the true material over {} bins: median |log| {:.3}, p90 {:.3}",
                e.bins, e.median_abs_log, e.p90_abs_log
            );
        }
        Outcome::Stopped { new_positions } => println!("stopped after {new_positions}"),
        Outcome::LampConstant(k) => println!("lamp constant {k:?}"),
    }
    Ok(())
}
