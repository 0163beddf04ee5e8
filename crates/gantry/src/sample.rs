//! `gantry sample model|plan|measure|reconstruct`: measuring a new material from few samples
//! (thesis ch. 6 and beyond; the `sampling` crate's jobs).

use anyhow::Result;
use clap::Subcommand;
use sampling::{MeasureJob, ModelJob, PlanJob, ReconstructJob};

/// Subcommands of `gantry sample`.
#[derive(Subcommand, Debug)]
pub enum SampleCommand {
    /// Learn what a method needs (training tables, PCA basis, wavelet basis) from a corpus.
    Model(ModelJob),
    /// Choose the points to measure: CSV with header theta_h,theta_d,phi_d,channel.
    Plan(PlanJob),
    /// "Measure" a plan on a material (planar-sample gonioreflectometer model with noise).
    Measure(MeasureJob),
    /// Reconstruct a full table from the measured values of a plan.
    Reconstruct(ReconstructJob),
}

/// Runs a `gantry sample` subcommand.
pub fn run(cmd: SampleCommand) -> Result<()> {
    let report = match cmd {
        SampleCommand::Model(a) => a.run()?,
        SampleCommand::Plan(a) => a.run()?,
        SampleCommand::Measure(a) => a.run()?,
        SampleCommand::Reconstruct(a) => a.run()?,
    };
    println!("{report}");
    Ok(())
}
