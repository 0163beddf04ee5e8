//! # recover — materials from photographs (thesis §7.2.3)
//!
//! Estimates the reflectance of an object of known shape, seen by a known camera under known
//! point lights and/or a known environment map, from one or more linear HDR photographs, with
//! the log-space PCA model of `reduce` (thesis chapter 4) as the space of materials:
//!
//! * [`scene`]: the `render` scene TOML with the object's material left unknown;
//! * [`functional`]: every usable pixel as a precomputed linear functional of the BRDF;
//! * [`fit`]: Levenberg–Marquardt on the PCA coefficients (the table is `exp` of the linear
//!   model) with an analytic Jacobian, a Gaussian prior from the corpus, a Huber loss against
//!   outlier pixels, and nominal coefficient uncertainties;
//! * [`recognize`]: ranking known materials by how well each explains the photos;
//! * [`metrics`]: the table errors used to validate it, and the albedo check;
//! * [`RecoverJob`]: the job behind `gantry recover`, options in, `run()`, a [`RecoverReport`] out.
//!
//! The recovered table is non-negative (`exp(y) − floor`, clamped) and reciprocal (every bin
//! of the MERL parametrisation is shared by (ωi, ωo) and (ωo, ωi)) by construction; its
//! directional albedo is checked with `brdf::summary` and, on request, scaled down to 1.
//!
//! ```
//! use recover::{functional::FunctionalOptions, scene::RecoveryScene};
//! // A 16 × 16 view of a sphere of unknown material under one point light.
//! let scene = RecoveryScene::parse(r#"
//!     [camera]
//!     position = [0.0, 0.0, 4.0]
//!     look_at = [0.0, 0.0, 0.0]
//!     fov = 35.0
//!     width = 16
//!     height = 16
//!     [[objects]]
//!     kind = "sphere"
//!     center = [0.0, 0.0, 0.0]
//!     radius = 1.0
//!     material = "unknown"
//!     [[lights]]
//!     kind = "point"
//!     position = [2.0, 2.0, 4.0]
//!     intensity = [20.0, 20.0, 20.0]
//! "#, std::path::Path::new(".")).unwrap();
//! let f = recover::functional::Functionals::build(&scene, &FunctionalOptions::default()).unwrap();
//! // A Lambertian table of albedo 0.5 seen through the functionals is the shading ρ/π · cos · I/r².
//! let lambert = brdf::MerlTable::tabulate(&brdf::analytic::Lambert { kd: [0.5; 3] });
//! let pixels = f.apply_table(&lambert);
//! assert!(f.len() > 50 && pixels.iter().all(|p| p[0] >= 0.0));
//! ```

#![warn(missing_docs)]
// Index loops over channels and rows mirror the sums of the pixel model.
#![allow(clippy::needless_range_loop)]

pub mod error;
pub mod fit;
pub mod functional;
mod job;
pub mod metrics;
pub mod photo;
pub mod recognize;
pub mod scene;

use serde::Serialize;

pub use error::{RecoverError, Result};
pub use fit::{Fit, FitOptions, LocalModel, Observation, Problem, TablePrior};
pub use functional::{FunctionalOptions, Functionals};
pub use job::{ImageReport, RecoverJob, RecoverReport};
pub use photo::Photo;
pub use recognize::Ranked;
pub use scene::RecoveryScene;

/// How the number of coefficients is chosen.
#[derive(Debug, Clone, PartialEq)]
pub enum Components {
    /// This many.
    Fixed(usize),
    /// The candidate with the lowest held-out residual in a two-fold cross-validation over
    /// 8 × 8 pixel blocks.
    CrossValidate(Vec<usize>),
}

/// Recovery settings.
#[derive(Debug, Clone, PartialEq)]
pub struct RecoverOptions {
    /// Number of PCA coefficients.
    pub components: Components,
    /// Fit settings.
    pub fit: FitOptions,
    /// Extra starts of the fit at the best-ranked corpus materials (besides the mean).
    pub extra_starts: usize,
    /// Scale the table down when its directional albedo exceeds 1.
    pub enforce_albedo: bool,
    /// Coarse-to-fine: with more rows than this in all, the ranking and the multi-start fit
    /// run on every `m`-th row (about this many rows), and the winner is refined on all rows
    /// (0 = always all rows).
    pub coarse_rows: usize,
}

impl Default for RecoverOptions {
    fn default() -> Self {
        RecoverOptions {
            components: Components::Fixed(45),
            fit: FitOptions::default(),
            extra_starts: 1,
            enforce_albedo: true,
            coarse_rows: 20_000,
        }
    }
}

/// A cross-validation score.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct CvScore {
    /// Number of coefficients.
    pub k: usize,
    /// Held-out RMS log residual (both folds).
    pub held_out: f64,
}

/// What [`recover`] found.
#[derive(Debug, Clone)]
pub struct Recovery {
    /// Coefficients used.
    pub k: usize,
    /// The fit.
    pub fit: Fit,
    /// The corpus materials ranked by how well their PCA-k representation explains the photos.
    pub ranking: Vec<Ranked>,
    /// Cross-validation scores (empty for a fixed `k`).
    pub cross_validation: Vec<CvScore>,
    /// The recovered table.
    pub table: brdf::MerlTable,
    /// Largest directional albedo per channel before any scaling.
    pub max_albedo: [f64; 3],
    /// Factor the table was scaled by to keep the albedo ≤ 1 (1 = none).
    pub albedo_scale: f64,
    /// Predicted radiance of every row of every observation.
    pub predictions: Vec<Vec<[f64; 3]>>,
}

/// Full table of PCA coefficients `x` (values clamped to ≥ 0).
pub fn synthesize_table(model: &reduce::model::Model, x: &[f64]) -> Result<brdf::MerlTable> {
    fit::check_model_grid(model)?;
    Ok(brdf::MerlTable::from_values(model.synthesize(x)?)?)
}

fn block_folds(obs: &[Observation]) -> [Vec<Vec<bool>>; 2] {
    let a: Vec<Vec<bool>> = obs
        .iter()
        .map(|o| {
            let w = o.functionals.width;
            o.functionals
                .pixels
                .iter()
                .map(|&p| {
                    let (x, y) = (p as usize % w, p as usize / w);
                    (x / 8 + y / 8) % 2 == 0
                })
                .collect()
        })
        .collect();
    let b = a.iter().map(|v| v.iter().map(|x| !x).collect()).collect();
    [a, b]
}

fn fit_multistart(
    problem: &Problem,
    model: &reduce::model::Model,
    local: &LocalModel,
    opts: &RecoverOptions,
) -> Result<(Fit, Vec<Ranked>)> {
    let ranking = recognize::rank_model_corpus(problem, model, local);
    let mut starts = vec![vec![0.0; local.k]];
    for r in ranking.iter().take(opts.extra_starts) {
        let i = model.names.iter().position(|n| *n == r.name).unwrap_or(0);
        starts.push((0..local.k).map(|j| model.pca.coords[(i, j)]).collect());
    }
    let mut best: Option<Fit> = None;
    for s in &starts {
        let f = problem.fit(s, &opts.fit)?;
        tracing::debug!(
            objective = f.objective,
            iterations = f.iterations,
            "fit from a start"
        );
        if best.as_ref().is_none_or(|b| f.objective < b.objective) {
            best = Some(f);
        }
    }
    Ok((best.expect("at least one start"), ranking))
}

/// Recovers a material from observations with the model.
pub fn recover(
    model: &reduce::model::Model,
    observations: &[Observation],
    opts: &RecoverOptions,
) -> Result<Recovery> {
    fit::check_model_grid(model)?;
    if observations.is_empty() || observations.iter().all(|o| o.functionals.is_empty()) {
        return Err(RecoverError::InvalidParameter("no observation".into()));
    }
    let fs: Vec<&Functionals> = observations.iter().map(|o| &o.functionals).collect();
    let (k, cross_validation) = match &opts.components {
        Components::Fixed(k) => (*k, Vec::new()),
        Components::CrossValidate(ks) => {
            if ks.is_empty() {
                return Err(RecoverError::InvalidParameter("no candidate k".into()));
            }
            let folds = block_folds(observations);
            let mut scores = Vec::new();
            for &k in ks {
                let local = LocalModel::new(model, k, &fs)?;
                let mut s2 = 0.0;
                for f in 0..2 {
                    let train = Problem::new(&local, observations, &opts.fit)?
                        .with_filter(folds[f].clone());
                    let test = Problem::new(&local, observations, &opts.fit)?
                        .with_filter(folds[1 - f].clone());
                    let fit = train.fit(&vec![0.0; k], &opts.fit)?;
                    let r = test.residual_rms(&fit.coefficients);
                    s2 += r.iter().map(|v| v * v).sum::<f64>() / r.len() as f64;
                }
                scores.push(CvScore {
                    k,
                    held_out: (s2 / 2.0).sqrt(),
                });
            }
            let best = scores
                .iter()
                .min_by(|a, b| a.held_out.total_cmp(&b.held_out))
                .expect("non-empty")
                .k;
            (best, scores)
        }
    };
    let local = LocalModel::new(model, k, &fs)?;
    let prior = if opts.fit.table_prior > 0.0 {
        let p = TablePrior::new(model, &local, 16)?;
        tracing::debug!(bins = p.bins, "table prior");
        Some(p)
    } else {
        None
    };
    fn with_prior<'p>(p: Problem<'p>, prior: &Option<TablePrior>) -> Problem<'p> {
        match prior {
            Some(t) => p.with_table_prior(t),
            None => p,
        }
    }
    let problem = with_prior(Problem::new(&local, observations, &opts.fit)?, &prior);
    let rows: usize = observations.iter().map(|o| o.functionals.len()).sum();
    let (fit, ranking) = if opts.coarse_rows > 0 && rows > 2 * opts.coarse_rows {
        // coarse: ranking and starts on a row subset; fine: the winner on all rows
        let step = rows.div_ceil(opts.coarse_rows);
        let coarse_obs: Vec<Observation> = observations.iter().map(|o| o.every(step)).collect();
        let cfs: Vec<&Functionals> = coarse_obs.iter().map(|o| &o.functionals).collect();
        let coarse_local = LocalModel::new(model, k, &cfs)?;
        let coarse = with_prior(Problem::new(&coarse_local, &coarse_obs, &opts.fit)?, &prior);
        let (cf, ranking) = fit_multistart(&coarse, model, &coarse_local, opts)?;
        tracing::debug!(step, iterations = cf.iterations, "coarse fit");
        (problem.fit(&cf.coefficients, &opts.fit)?, ranking)
    } else {
        fit_multistart(&problem, model, &local, opts)?
    };
    let mut table = synthesize_table(model, &fit.coefficients)?;
    let max_albedo = metrics::max_directional_albedo(&table);
    let peak = max_albedo.iter().copied().fold(0.0, f64::max);
    let mut albedo_scale = 1.0;
    if opts.enforce_albedo && peak > 1.0 {
        albedo_scale = 1.0 / peak;
        for v in table.raw_mut() {
            if *v > 0.0 {
                *v *= albedo_scale;
            }
        }
        tracing::warn!(
            peak,
            "recovered table scaled down to keep its albedo at most 1"
        );
    }
    let predictions = problem.predict(&fit.coefficients);
    Ok(Recovery {
        k,
        fit,
        ranking,
        cross_validation,
        table,
        max_albedo,
        albedo_scale,
        predictions,
    })
}

/// The photograph (left) beside the re-render of the recovered material (right: predicted
/// radiance on the object's pixels, the photo elsewhere), and the exposure that maps the
/// photo's 99th-percentile object radiance to 1 (for a PNG).
pub fn comparison_image(
    photo: &Photo,
    functionals: &Functionals,
    predictions: &[[f64; 3]],
) -> Result<(render::Image, f64)> {
    let (w, h) = (photo.width, photo.height);
    let rerender = functionals.to_image(predictions, Some(&photo.pixels));
    let mut img = render::Image::new(2 * w, h)?;
    for y in 0..h {
        for x in 0..w {
            img.set(x, y, photo.pixels[y * w + x]);
            img.set(w + x, y, rerender[y * w + x]);
        }
    }
    let mut lum: Vec<f32> = functionals
        .pixels
        .iter()
        .map(|&p| {
            photo.pixels[p as usize]
                .iter()
                .fold(0.0f32, |a, &b| a.max(b))
        })
        .filter(|v| v.is_finite())
        .collect();
    let exposure = if lum.is_empty() {
        1.0
    } else {
        let i = (lum.len() * 99 / 100).min(lum.len() - 1);
        lum.select_nth_unstable_by(i, |a, b| a.total_cmp(b));
        1.0 / (lum[i] as f64).max(1e-12)
    };
    Ok((img, exposure))
}
