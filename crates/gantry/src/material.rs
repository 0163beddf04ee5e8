//! `gantry info`, `gantry eval` and `gantry convert`: commands on a single material.

use anyhow::{bail, Context, Result};
use brdf::summary::{summarize, SummaryOptions};
use brdf::table::Interpolation;
use brdf::{Brdf, HalfDiff};
use clap::{Args, ValueEnum};
use std::io::{BufWriter, Write};
use std::path::{Path, PathBuf};

/// Arguments of `gantry info`.
#[derive(Args, Debug)]
pub struct InfoArgs {
    /// Material spec (see docs/material-spec.md), e.g. merl:chrome or ggx:alpha=0.2.
    spec: String,
    /// Print JSON instead of text.
    #[arg(long)]
    json: bool,
}

/// How a tabulated material is looked up between grid points.
#[derive(ValueEnum, Clone, Copy, Debug)]
enum Interp {
    /// The bin containing the query (MERL reference reader).
    Nearest,
    /// Trilinear interpolation between grid points.
    Trilinear,
}

/// Arguments of `gantry eval`.
#[derive(Args, Debug)]
pub struct EvalArgs {
    /// Material spec.
    spec: String,
    /// CSV file with header theta_h,theta_d,phi_d (radians); '-' reads stdin.
    #[arg(long)]
    angles: PathBuf,
    /// Lookup used for tabulated materials.
    #[arg(long, value_enum, default_value = "nearest")]
    interp: Interp,
}

/// Arguments of `gantry convert`.
#[derive(Args, Debug)]
pub struct ConvertArgs {
    /// Material spec.
    spec: String,
    /// Output MERL .binary file (written atomically); any other extension is refused.
    #[arg(long)]
    out: PathBuf,
}

fn load(spec: &str) -> Result<brdf::spec::Material> {
    brdf::spec::load(spec).with_context(|| format!("cannot load material '{spec}'"))
}

/// `gantry info`.
pub fn info(args: InfoArgs) -> Result<()> {
    let material = load(&args.spec)?;
    let table = material.tabulate();
    let summary = summarize(&material, &table, &SummaryOptions::default());
    if args.json {
        println!("{}", serde_json::to_string_pretty(&summary)?);
    } else {
        println!("{summary}");
    }
    Ok(())
}

/// Reads `theta_h,theta_d,phi_d` rows from a CSV file (or stdin for `-`); see
/// [`brdf::angles::parse_csv`].
pub fn read_angles(path: &Path) -> Result<Vec<HalfDiff>> {
    let text = if path.as_os_str() == "-" {
        std::io::read_to_string(std::io::stdin()).context("cannot read standard input")?
    } else {
        std::fs::read_to_string(path).with_context(|| format!("{}: cannot read", path.display()))?
    };
    Ok(brdf::angles::parse_csv(&text, &path.display().to_string())?)
}

/// `gantry eval`.
pub fn eval(args: EvalArgs) -> Result<()> {
    let points = read_angles(&args.angles)?;
    let mut material = load(&args.spec)?;
    if let brdf::spec::Material::Table(t) = &mut material {
        let mode = match args.interp {
            Interp::Nearest => Interpolation::Nearest,
            Interp::Trilinear => Interpolation::Trilinear,
        };
        *t = t.clone().with_interpolation(mode);
    }
    use rayon::prelude::*;
    let values: Vec<brdf::Rgb> = points
        .par_iter()
        .map(|hd| material.eval_half_diff(hd))
        .collect();
    let stdout = std::io::stdout();
    let mut out = BufWriter::new(stdout.lock());
    writeln!(out, "theta_h,theta_d,phi_d,r,g,b")?;
    for (p, v) in points.iter().zip(values) {
        writeln!(
            out,
            "{},{},{},{:e},{:e},{:e}",
            p.theta_h, p.theta_d, p.phi_d, v[0], v[1], v[2]
        )?;
    }
    out.flush()?;
    Ok(())
}

/// `gantry convert`.
pub fn convert(args: ConvertArgs) -> Result<()> {
    let ext = args.out.extension().and_then(|e| e.to_str()).unwrap_or("");
    if !ext.eq_ignore_ascii_case("binary") {
        bail!(
            "{}: unknown output format '.{ext}': `gantry convert` writes MERL tables, name the \
             output FILE.binary",
            args.out.display()
        );
    }
    let material = load(&args.spec)?;
    let table = material.tabulate();
    brdf::merl::write(&args.out, &table)
        .with_context(|| format!("cannot write {}", args.out.display()))?;
    tracing::info!(out = %args.out.display(), missing = table.missing_fraction(), "wrote table");
    Ok(())
}
