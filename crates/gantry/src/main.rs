//! `gantry`: the command-line front end of the data-driven reflectance toolkit.
//!
//! The binary only composes the library crates; every subcommand lives in its own module.

use anyhow::Result;
use clap::{Parser, Subcommand};
use std::process::ExitCode;

mod calibrate;
mod capture;
mod corpus_cmd;
mod fit_cmd;
mod material;
mod model;
mod progress;
mod recover_cmd;
mod render_cmd;
mod sample;
mod serve_cmd;
mod traits_cmd;
mod wavelet_cmd;

/// Measure, model, compress and render isotropic BRDFs.
#[derive(Parser, Debug)]
#[command(name = "gantry", version, about, propagate_version = true)]
struct Cli {
    /// More log output (-v info, -vv debug, -vvv trace). Logs go to stderr.
    #[arg(short, long, action = clap::ArgAction::Count, global = true)]
    verbose: u8,

    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand, Debug)]
enum Command {
    /// Summarise a material: albedo against incidence angle, peak, reciprocity, missing bins.
    Info(material::InfoArgs),
    /// List the material-spec forms and the corpus-store formats this program reads.
    Forms,
    /// Evaluate a material at the angles of a CSV file (header theta_h,theta_d,phi_d, radians).
    Eval(material::EvalArgs),
    /// Tabulate a material on the MERL grid and write it as a MERL .binary file.
    Convert(material::ConvertArgs),
    /// Geometric calibration of camera, lamp circle and sphere.
    Calibrate(calibrate::CalibrateArgs),
    /// Measure a BRDF: calibration, dark frame, bracketed exposures at every lamp position, HDR,
    /// binning, validation (resumable; --sim runs on the simulated rig).
    Capture(capture::CaptureArgs),
    /// Re-run HDR (from stored frames) and binning of a capture directory without capturing.
    Rebin(capture::RebinArgs),
    /// Models of the space of BRDFs (PCA, charting).
    #[command(subcommand)]
    Model(model::ModelCommand),
    /// Render a scene file, or a figure: sphere, teapot, strip.
    Render(render::RenderJob),
    /// Recover a material from photographs of an object of known shape, camera and lighting.
    Recover(recover::RecoverJob),
    /// Sparse acquisition: learn, plan, measure, reconstruct.
    #[command(subcommand)]
    Sample(sample::SampleCommand),
    /// Common Wavelet Basis of a corpus, and materials compressed onto it.
    #[command(subcommand)]
    Wavelet(wavelet_cmd::WaveletCommand),
    /// Fit an analytic model to a material, or compare every model across a corpus.
    Fit(fit::FitJob),
    /// Trait vectors (user-defined parameterization): fit, score, path.
    #[command(subcommand)]
    Traits(traits_cmd::TraitsCommand),
    /// Add scaled traits to a material, stopping at the border of the physically valid set.
    Edit(traits::EditJob),
    /// The material viewer and editor in the browser (local HTTP server, 127.0.0.1 by default).
    Serve(serve_cmd::ServeArgs),
    /// Corpus stores (chunked Zarr v3): pack, synthesise, inspect, out-of-core PCA.
    #[command(subcommand)]
    Corpus(corpus_cmd::CorpusCommand),
}

fn init_logging(verbose: u8) {
    let level = match verbose {
        0 => "warn",
        1 => "info",
        2 => "debug",
        _ => "trace",
    };
    let filter = tracing_subscriber::EnvFilter::try_from_env("GANTRY_LOG")
        .unwrap_or_else(|_| tracing_subscriber::EnvFilter::new(level));
    let _ = tracing_subscriber::fmt()
        .with_env_filter(filter)
        .with_writer(std::io::stderr)
        .try_init();
}

fn run(cli: Cli) -> Result<()> {
    match cli.command {
        Command::Info(a) => material::info(a),
        Command::Eval(a) => material::eval(a),
        Command::Convert(a) => material::convert(a),
        Command::Calibrate(a) => calibrate::run(a),
        Command::Capture(a) => capture::capture(a),
        Command::Rebin(a) => capture::rebin(a),
        Command::Model(c) => model::run(c),
        Command::Render(a) => render_cmd::run(a),
        Command::Recover(a) => recover_cmd::run(a),
        Command::Sample(c) => sample::run(c),
        Command::Wavelet(c) => wavelet_cmd::run(c),
        Command::Fit(a) => fit_cmd::run(a),
        Command::Traits(c) => traits_cmd::run(c),
        Command::Edit(a) => traits_cmd::edit(a),
        Command::Serve(a) => serve_cmd::run(a),
        Command::Forms => {
            let catalogue = catalogue::Catalogue::workspace();
            for form in catalogue.forms() {
                println!("{form}");
            }
            for store in catalogue.store_formats() {
                println!("--corpus: {store}");
            }
            Ok(())
        }
        Command::Corpus(c) => corpus_cmd::run(c),
    }
}

fn main() -> ExitCode {
    let cli = Cli::parse();
    init_logging(cli.verbose);
    // Every material-spec form and corpus store of the workspace, as the Python package reads
    // them (docs/material-spec.md).
    catalogue::Catalogue::workspace().install();
    match run(cli) {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("error: {}", error_chain(&e));
            ExitCode::FAILURE
        }
    }
}

/// An error and its causes on one line, each cause once: many library errors already show their
/// cause in their own message, which `{:#}` would print again.
fn error_chain(e: &anyhow::Error) -> String {
    let mut line = String::new();
    for cause in e.chain() {
        let text = cause.to_string();
        if line.contains(&text) {
            continue;
        }
        if !line.is_empty() {
            line.push_str(": ");
        }
        line.push_str(&text);
    }
    line
}
