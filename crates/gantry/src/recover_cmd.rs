//! `gantry recover`: a material from photographs of an object of known shape and lighting.

use anyhow::{bail, Context, Result};
use clap::Args;
use recover::{Components, FunctionalOptions, Functionals, Observation, Photo, RecoveryScene};
use serde::Serialize;
use std::path::{Path, PathBuf};
use std::time::Instant;

/// Arguments of `gantry recover`.
#[derive(Args, Debug)]
pub struct RecoverArgs {
    /// Scene TOML with the object's material unknown (once, or once per image).
    #[arg(long, required = true)]
    scene: Vec<PathBuf>,
    /// Linear photographs (.exr, .hdr; 8-bit images are sRGB-decoded and clip at 1).
    #[arg(long, required = true)]
    image: Vec<PathBuf>,
    /// Masks (once per image; white = use the pixel).
    #[arg(long)]
    mask: Vec<PathBuf>,
    /// Model file (`gantry model build`).
    #[arg(long)]
    model: PathBuf,
    /// Recovered MERL .binary table.
    #[arg(long)]
    out: PathBuf,
    /// JSON report (a side-by-side PNG per image is written beside it).
    #[arg(long)]
    report: Option<PathBuf>,
    /// Number of coefficients; 0 = choose by cross-validation among 10, 20, 30, 45 (and 60).
    #[arg(long, default_value_t = 45)]
    k: usize,
    /// Monte Carlo samples per pixel for an environment map.
    #[arg(long, default_value_t = 64)]
    env_samples: usize,
    /// Use every n-th pixel in x and y.
    #[arg(long, default_value_t = 1)]
    stride: usize,
    /// Weight of the corpus prior.
    #[arg(long, default_value_t = 1.0)]
    prior: f64,
    /// Saturation level of HDR images (pixels at or above are left out).
    #[arg(long)]
    saturation: Option<f32>,
}

#[derive(Serialize)]
struct ImageReport {
    image: PathBuf,
    pixels_used: usize,
    residual_rms_log: f64,
    comparison_png: Option<PathBuf>,
}

#[derive(Serialize)]
struct Report {
    model: PathBuf,
    k: usize,
    coefficients: Vec<f64>,
    uncertainty: Vec<f64>,
    residual_scale: f64,
    iterations: usize,
    images: Vec<ImageReport>,
    cross_validation: Vec<recover::CvScore>,
    max_directional_albedo: [f64; 3],
    albedo_scale: f64,
    nearest_corpus_materials: Vec<recover::Ranked>,
    seconds: f64,
}

/// Runs `gantry recover`.
pub fn run(a: RecoverArgs) -> Result<()> {
    let t0 = Instant::now();
    if a.scene.len() != 1 && a.scene.len() != a.image.len() {
        bail!("give one --scene, or one per --image");
    }
    if !a.mask.is_empty() && a.mask.len() != a.image.len() {
        bail!("give one --mask per --image, or none");
    }
    let model = reduce::model::Model::load(&a.model)
        .with_context(|| format!("cannot load model {}", a.model.display()))?;
    recover::fit::check_model_grid(&model)?;
    let fopts = FunctionalOptions {
        env_samples: a.env_samples,
        stride: a.stride,
        ..Default::default()
    };
    let mut obs = Vec::new();
    let mut photos = Vec::new();
    for (i, path) in a.image.iter().enumerate() {
        let sp = &a.scene[if a.scene.len() == 1 { 0 } else { i }];
        let scene = RecoveryScene::load(sp)
            .with_context(|| format!("cannot use scene {}", sp.display()))?;
        let mut photo = Photo::read(path)?;
        if let Some(s) = a.saturation {
            photo = photo.with_saturation(s);
        }
        let mask = match a.mask.get(i) {
            Some(m) => Some(recover::photo::read_mask_for(m, &photo)?),
            None => None,
        };
        let f = Functionals::build(&scene, &fopts)?;
        let dark_bg = scene.scene.environment.is_none();
        obs.push(Observation::checked(
            i,
            f,
            &photo,
            mask.as_deref(),
            dark_bg,
        )?);
        photos.push(photo);
    }
    let components = if a.k == 0 {
        let ks = [10, 20, 30, 45, 60]
            .into_iter()
            .filter(|&k| k <= model.components())
            .collect();
        Components::CrossValidate(ks)
    } else {
        Components::Fixed(a.k)
    };
    let opts = recover::RecoverOptions {
        components,
        fit: recover::FitOptions {
            prior_weight: a.prior,
            ..Default::default()
        },
        ..Default::default()
    };
    let rec = recover::recover(&model, &obs, &opts)?;
    let table = rec
        .table
        .clone()
        .with_name(format!("recovered from {} image(s)", a.image.len()));
    brdf::merl::write(&a.out, &table)
        .with_context(|| format!("cannot write {}", a.out.display()))?;
    if let Some(rp) = &a.report {
        let mut images = Vec::new();
        for (i, (o, photo)) in obs.iter().zip(&photos).enumerate() {
            let png = side_png(rp, i);
            let (img, exposure) =
                recover::comparison_image(photo, &o.functionals, &rec.predictions[i])?;
            img.write_png(
                &png,
                &render::Tonemap {
                    exposure,
                    operator: render::TonemapOperator::Clamp,
                },
            )?;
            images.push(ImageReport {
                image: a.image[i].clone(),
                pixels_used: o.functionals.len(),
                residual_rms_log: rec.fit.residual_rms[i],
                comparison_png: Some(png),
            });
        }
        let report = Report {
            model: a.model.clone(),
            k: rec.k,
            coefficients: rec.fit.coefficients.clone(),
            uncertainty: rec.fit.uncertainty.clone(),
            residual_scale: rec.fit.sigma,
            iterations: rec.fit.iterations,
            images,
            cross_validation: rec.cross_validation.clone(),
            max_directional_albedo: rec.max_albedo,
            albedo_scale: rec.albedo_scale,
            nearest_corpus_materials: rec.ranking.iter().take(10).cloned().collect(),
            seconds: t0.elapsed().as_secs_f64(),
        };
        let json = serde_json::to_vec_pretty(&report)?;
        brdf::write_atomic(rp, &json)?;
    }
    println!(
        "recovered k = {} from {} image(s): residual RMS (log) {:?}; nearest corpus material {}; {:.1} s",
        rec.k,
        a.image.len(),
        rec.fit.residual_rms,
        rec.ranking.first().map(|r| r.name.as_str()).unwrap_or("-"),
        t0.elapsed().as_secs_f64()
    );
    Ok(())
}

fn side_png(report: &Path, i: usize) -> PathBuf {
    let stem = report
        .file_stem()
        .and_then(|s| s.to_str())
        .unwrap_or("report");
    report.with_file_name(format!("{stem}-image{i}.png"))
}
