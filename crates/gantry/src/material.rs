//! `gantry info`, `gantry eval` and `gantry convert`: commands on a single material.

use anyhow::{bail, Context, Result};
use brdf::Interpolation;
use brdf::{summarize, SummaryOptions};
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
    /// Output file, written atomically in the format its extension names: `.binary` (a MERL
    /// table) or `.bsdf` (an RGL tensor file for Mitsuba 3 and pbrt-v4); any other extension
    /// is refused.
    #[arg(long)]
    out: PathBuf,
    /// `.bsdf` only: rows and columns of the warped reflectance grid.
    #[arg(long, default_value_t = 32)]
    resolution: usize,
    /// `.bsdf` only: incident elevations.
    #[arg(long, default_value_t = 16)]
    theta_i: usize,
    /// `.bsdf` only: write a spectral file (360–830 nm; pbrt-v4, Mitsuba's spectral variants)
    /// instead of an RGB one (Mitsuba's RGB variants).
    #[arg(long)]
    spectral: bool,
}

fn load(spec: &str) -> Result<brdf::Material> {
    brdf::load(spec).with_context(|| format!("cannot load material '{spec}'"))
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
/// [`brdf::parse_csv`].
pub fn read_angles(path: &Path) -> Result<Vec<HalfDiff>> {
    let text = if path.as_os_str() == "-" {
        std::io::read_to_string(std::io::stdin()).context("cannot read standard input")?
    } else {
        std::fs::read_to_string(path).with_context(|| format!("{}: cannot read", path.display()))?
    };
    Ok(brdf::parse_csv(&text, &path.display().to_string())?)
}

/// `gantry eval`.
pub fn eval(args: EvalArgs) -> Result<()> {
    let points = read_angles(&args.angles)?;
    let mut material = load(&args.spec)?;
    if let brdf::Material::Table(t) = &mut material {
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
    if !catalogue::WRITE_FORMATS
        .iter()
        .any(|f| f.eq_ignore_ascii_case(ext))
    {
        bail!(
            "{}: unknown output format '.{ext}': `gantry convert` writes .binary (MERL table) or \
             .bsdf (RGL tensor file)",
            args.out.display()
        );
    }
    let material = load(&args.spec)?;
    let options = rgl_bsdf::WriteOptions {
        resolution: args.resolution,
        vndf_resolution: args.resolution,
        theta_i: args.theta_i,
        spectral: args.spectral,
        description: args.spec.clone(),
        ..Default::default()
    };
    let written = catalogue::write_material(&material, &args.out, &options)?;
    println!("{written}");
    Ok(())
}
