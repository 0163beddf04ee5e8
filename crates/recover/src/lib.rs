//! # recover — materials from photographs (thesis §7.2.3)
//!
//! Estimates the reflectance of an object of known shape, seen by a known camera under known
//! point lights and/or a known environment map, from one or more linear HDR photographs, with
//! the log-space PCA model of `reduce` (thesis chapter 4) as the space of materials:
//!
//! In the order of the work:
//!
//! 1. [`RecoveryScene`] is a `render` scene TOML whose object's material is left unknown;
//!    [`Photo`] reads the linear HDR photographs of it.
//! 2. [`Functionals`] turns every usable pixel into a precomputed linear functional of the BRDF
//!    ([`FunctionalOptions`]), so a candidate table is scored by one sparse product.
//! 3. [`Problem`] holds the observations ([`Observation`]) against a [`LocalModel`] of the PCA
//!    space; its fit ([`FitOptions`], giving a [`Fit`]) is Levenberg–Marquardt on the PCA
//!    coefficients (the table is `exp` of the linear model) with an analytic Jacobian, a
//!    Gaussian prior from the corpus, a Huber loss against outlier pixels, and nominal
//!    coefficient uncertainties.
//! 4. [`recover()`] chains ranking, multi-start fit and coarse-to-fine refinement
//!    ([`RecoverOptions`]); [`rank_tables`] and [`rank_model_corpus`] rank known materials by
//!    how well each explains the photographs (recognition, [`Ranked`]).
//! 5. [`cosine_weighted_relative_rms`] and [`log_relative_rms`] measure a recovered table
//!    against the true one.
//! 6. [`RecoverJob`] is the job behind `gantry recover`: options in, `run()`, a
//!    [`RecoverReport`] out.
//!
//! The recovered table is non-negative (`exp(y) − floor`, clamped) and reciprocal (every bin
//! of the MERL parametrisation is shared by (ωi, ωo) and (ωo, ωi)) by construction; its
//! directional albedo is checked with `brdf::summary` and, on request, scaled down to 1.
//!
//! ```
//! use recover::{FunctionalOptions, RecoveryScene};
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
//! let f = recover::Functionals::build(&scene, &FunctionalOptions::default()).unwrap();
//! // A Lambertian table of albedo 0.5 seen through the functionals is the shading ρ/π · cos · I/r².
//! let lambert = brdf::MerlTable::tabulate(&brdf::analytic::Lambert { kd: [0.5; 3] });
//! let pixels = f.apply_table(&lambert);
//! assert!(f.len() > 50 && pixels.iter().all(|p| p[0] >= 0.0));
//! ```

#![warn(missing_docs)]
// Index loops over channels and rows mirror the sums of the pixel model.
#![allow(clippy::needless_range_loop)]

mod combination;
mod error;
mod fit;
mod functional;
mod job;
mod metrics;
mod photo;
mod recognize;
mod scene;

pub use metrics::{cosine_weighted_relative_rms, log_relative_rms};
pub use photo::{srgb_decode, srgb_encode};
pub use recognize::{class_of, rank_model_corpus, rank_tables, METALS};
pub use scene::UnknownBrdf;

use serde::Serialize;

pub use combination::{
    combine, cross_validate_combination, fit_combination, Combination, CombinationOptions,
};
pub use error::{RecoverError, Result};
pub use fit::{Fit, FitOptions, LocalModel, Observation, Problem, TablePrior};
pub use functional::{EnvSampling, FunctionalOptions, Functionals};
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
    /// Levenberg–Marquardt iterations of that refinement on all rows (0 = keep the coarse
    /// fit's coefficients; their uncertainty and residuals are still those of all rows).
    pub refine_iterations: usize,
}

impl Default for RecoverOptions {
    fn default() -> Self {
        RecoverOptions {
            components: Components::Fixed(45),
            fit: FitOptions::default(),
            extra_starts: 1,
            enforce_albedo: true,
            coarse_rows: 20_000,
            refine_iterations: FitOptions::default().max_iterations,
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
pub fn synthesize_table(model: &reduce::Model, x: &[f64]) -> Result<brdf::MerlTable> {
    fit::check_model_grid(model)?;
    Ok(brdf::MerlTable::from_values(model.synthesize(x)?)?)
}

/// The largest directional albedo of `table` per channel, and the factor the table was
/// scaled by (when `enforce` and the albedo exceeds 1) to bring it to 1.
pub(crate) fn limit_albedo(table: &mut brdf::MerlTable, enforce: bool) -> ([f64; 3], f64) {
    let max_albedo = metrics::max_directional_albedo(table);
    let peak = max_albedo.iter().copied().fold(0.0, f64::max);
    let mut albedo_scale = 1.0;
    if enforce && peak > 1.0 {
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
    (max_albedo, albedo_scale)
}

/// The two folds of the cross-validation over 8 × 8 pixel blocks (a checkerboard of blocks):
/// `folds[f][observation][row]` is whether the row is in fold `f`.
pub fn block_folds(obs: &[Observation]) -> [Vec<Vec<bool>>; 2] {
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
    model: &reduce::Model,
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
///
/// # Examples
///
/// ```
/// use recover::{log_relative_rms, recover, Components, RecoverOptions};
/// # use recover::{FunctionalOptions, Functionals, Observation, Photo, RecoveryScene};
/// // Four analytic materials on the MERL grid and the 3-component PCA model of them.
/// let specs = ["lambert:kd=0.7", "lambert:kd=0.2/0.3/0.6", "ggx:alpha=0.2,kd=0.1", "ggx:alpha=0.4,kd=0.4"];
/// let tables: Vec<brdf::MerlTable> = specs.iter().map(|s| brdf::load(s).unwrap().tabulate()).collect();
/// let mut corpus = reduce::Corpus::new(reduce::MATERIAL_DIM);
/// for (s, t) in specs.iter().zip(&tables) {
///     corpus.push_values(s.to_string(), &t.values()).unwrap();
/// }
/// let model = reduce::build_model(&corpus, 3, None, None).unwrap();
/// // A 24 × 24 view of a unit sphere under one point light, "photographed" in the third
/// // material: every pixel's radiance is its functional applied to the true table.
/// let light = RecoveryScene::point_light_toml([2.0, 2.0, 4.0], 25.0);
/// let scene = RecoveryScene::unit_sphere(24, &light).unwrap();
/// let functionals = Functionals::build(&scene, &FunctionalOptions::default()).unwrap();
/// let mut pixels = vec![[0.0f32; 3]; 24 * 24];
/// for (&p, v) in functionals.pixels.iter().zip(functionals.apply_table(&tables[2])) {
///     pixels[p as usize] = v.map(|x| x as f32);
/// }
/// let photo = Photo::new(24, 24, pixels).unwrap();
/// let observations = vec![Observation::new(functionals, &photo, None).unwrap()];
/// let opts = RecoverOptions { components: Components::Fixed(3), ..RecoverOptions::default() };
/// let found = recover(&model, &observations, &opts).unwrap();
/// assert_eq!(found.k, 3);
/// assert_eq!(found.ranking[0].name, specs[2]);
/// // The recovered table is the true one, non-negative and energy-conserving.
/// let err = log_relative_rms(&tables[2], &found.table);
/// assert!(err < 0.01, "relative log RMS error {err}");
/// assert!(found.table.values().iter().all(|v| *v >= 0.0));
/// assert!(found.max_albedo.iter().all(|a| *a <= 1.0));
/// ```
pub fn recover(
    model: &reduce::Model,
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
        let fine = FitOptions {
            max_iterations: opts.refine_iterations,
            ..opts.fit.clone()
        };
        (problem.fit(&cf.coefficients, &fine)?, ranking)
    } else {
        fit_multistart(&problem, model, &local, opts)?
    };
    let mut table = synthesize_table(model, &fit.coefficients)?;
    let (max_albedo, albedo_scale) = limit_albedo(&mut table, opts.enforce_albedo);
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
