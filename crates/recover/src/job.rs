//! The job behind `gantry recover`: photographs, scenes and a model in, a recovered table and
//! a serde report out. With the `cli` feature the options are also the command's arguments.

use std::fmt;
use std::path::{Path, PathBuf};
use std::time::Instant;

use serde::Serialize;

use crate::error::{RecoverError, Result};
use crate::{
    cross_validate_combination, fit_combination, recover, CombinationOptions, Components, CvScore,
    FitOptions, FunctionalOptions, Functionals, Observation, Photo, Ranked, RecoverOptions,
    RecoveryScene,
};

/// Recover a material from photographs of an object of known shape, camera and lighting.
#[derive(Debug, Clone)]
#[cfg_attr(feature = "cli", derive(clap::Args))]
pub struct RecoverJob {
    /// Scene TOML with the object's material unknown (once, or once per image).
    #[cfg_attr(feature = "cli", arg(long, required = true))]
    pub scene: Vec<PathBuf>,
    /// Linear photographs (.exr, .hdr; 8-bit images are sRGB-decoded and clip at 1).
    #[cfg_attr(feature = "cli", arg(long, required = true))]
    pub image: Vec<PathBuf>,
    /// Masks (once per image; white = use the pixel).
    #[cfg_attr(feature = "cli", arg(long))]
    pub mask: Vec<PathBuf>,
    /// Model file (`gantry model build`).
    #[cfg_attr(feature = "cli", arg(long))]
    pub model: PathBuf,
    /// Recovered MERL .binary table.
    #[cfg_attr(feature = "cli", arg(long))]
    pub out: PathBuf,
    /// JSON report (a side-by-side PNG per image is written beside it).
    #[cfg_attr(feature = "cli", arg(long))]
    pub report: Option<PathBuf>,
    /// Number of coefficients; 0 = choose by cross-validation among 10, 20, 30, 45 (and 60).
    #[cfg_attr(feature = "cli", arg(long, default_value_t = 45))]
    pub k: usize,
    /// Monte Carlo samples per pixel for an environment map.
    #[cfg_attr(feature = "cli", arg(long, default_value_t = 64))]
    pub env_samples: usize,
    /// Use every n-th pixel in x and y.
    #[cfg_attr(feature = "cli", arg(long, default_value_t = 1))]
    pub stride: usize,
    /// Weight of the corpus prior.
    #[cfg_attr(feature = "cli", arg(long, default_value_t = 1.0))]
    pub prior: f64,
    /// Saturation level of HDR images (pixels at or above are left out).
    #[cfg_attr(feature = "cli", arg(long))]
    pub saturation: Option<f32>,
    /// What the material is sought as: `pca` (the model's coefficients), `combination` (a
    /// non-negative combination of the `--corpus` materials, thesis §6.5) or `auto` (the one
    /// with the lower held-out residual over 8 × 8 pixel blocks).
    #[cfg_attr(feature = "cli", arg(long, default_value = "pca"))]
    pub family: String,
    /// The corpus of the `combination` family: material specs, folders of neural-BRDF weights,
    /// .binary files or corpus stores, as `gantry model build --corpus` reads them.
    #[cfg_attr(feature = "cli", arg(long, num_args = 1..))]
    pub corpus: Vec<PathBuf>,
}

/// The families [`RecoverJob::family`] names.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Family {
    Pca,
    Combination,
    Auto,
}

impl Family {
    fn parse(s: &str) -> Result<Family> {
        match s {
            "pca" => Ok(Family::Pca),
            "combination" => Ok(Family::Combination),
            "auto" => Ok(Family::Auto),
            _ => Err(RecoverError::InvalidParameter(format!(
                "unknown family {s:?} (expected pca, combination or auto)"
            ))),
        }
    }
}

/// Held-out residuals of the two families (`--family auto`).
#[derive(Debug, Clone, Serialize)]
pub struct FamilyScores {
    /// The PCA fit's held-out RMS log residual (at the chosen k).
    pub pca: f64,
    /// The combination's.
    pub combination: f64,
}

/// A corpus material and its coefficient in a recovered combination.
#[derive(Debug, Clone, Serialize)]
pub struct CombinationTerm {
    /// The corpus material.
    pub material: String,
    /// Its coefficient (≥ 0).
    pub coefficient: f64,
}

/// One photograph's part of a [`RecoverReport`].
#[derive(Debug, Clone, Serialize)]
pub struct ImageReport {
    /// The photograph.
    pub image: PathBuf,
    /// Pixels the fit used: on the object, lit, not saturated and not masked out.
    pub pixels_used: usize,
    /// RMS of the log residual over those pixels.
    pub residual_rms_log: f64,
    /// The side-by-side PNG (photo, rendering of the result), when a report file was asked for.
    pub comparison_png: Option<PathBuf>,
}

/// What [`RecoverJob::run`] recovered (the `--report` JSON).
#[derive(Debug, Clone, Serialize)]
pub struct RecoverReport {
    /// The model file.
    pub model: PathBuf,
    /// The family of the result: `pca` or `combination`.
    pub family: String,
    /// With `--family auto`: both families' held-out residuals.
    pub family_scores: Option<FamilyScores>,
    /// The combination's materials with a non-zero coefficient, largest first (empty for
    /// `pca`).
    pub combination: Vec<CombinationTerm>,
    /// Coefficients used (0 for a combination).
    pub k: usize,
    /// The recovered PCA coefficients (empty for a combination).
    pub coefficients: Vec<f64>,
    /// Their standard deviations.
    pub uncertainty: Vec<f64>,
    /// Scale of the residuals (PCA fit).
    pub residual_scale: f64,
    /// Solver iterations (PCA fit).
    pub iterations: usize,
    /// Per photograph.
    pub images: Vec<ImageReport>,
    /// MERL bins (of 1,458,000) the photographs constrain (`Observation::constrained_bins`);
    /// the model alone fixes the rest.
    pub bins_constrained: usize,
    /// The cross-validation scores, when k was chosen by it.
    pub cross_validation: Vec<CvScore>,
    /// The largest directional albedo of the recovered table, per channel.
    pub max_directional_albedo: [f64; 3],
    /// The scale applied to keep the albedo physical.
    pub albedo_scale: f64,
    /// The ten nearest corpus materials (PCA fit).
    pub nearest_corpus_materials: Vec<Ranked>,
    /// Wall time.
    pub seconds: f64,
}

impl fmt::Display for RecoverReport {
    /// One line: k (or the combination), images, residuals, the nearest corpus material and
    /// the time.
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let residuals: Vec<f64> = self.images.iter().map(|i| i.residual_rms_log).collect();
        if self.family == "combination" {
            let terms: Vec<String> = self
                .combination
                .iter()
                .take(4)
                .map(|t| format!("{} {:.3}", t.material, t.coefficient))
                .collect();
            return write!(
                f,
                "recovered a combination of {} corpus materials ({}) from {} image(s): \
                 residual RMS (log) {residuals:?}; {:.1} s",
                self.combination.len(),
                terms.join(", "),
                self.images.len(),
                self.seconds
            );
        }
        write!(
            f,
            "recovered k = {} from {} image(s): residual RMS (log) {residuals:?}; nearest corpus material {}; {:.1} s",
            self.k,
            self.images.len(),
            self.nearest_corpus_materials
                .first()
                .map_or("-", |r| r.name.as_str()),
            self.seconds
        )
    }
}

/// The side-by-side PNG of image `i` beside the report file.
fn side_png(report: &Path, i: usize) -> PathBuf {
    let stem = report
        .file_stem()
        .and_then(|s| s.to_str())
        .unwrap_or("report");
    report.with_file_name(format!("{stem}-image{i}.png"))
}

impl RecoverJob {
    fn check_counts(&self) -> Result<()> {
        if self.scene.len() != 1 && self.scene.len() != self.image.len() {
            return Err(RecoverError::InvalidParameter(
                "give one scene, or one per image".into(),
            ));
        }
        if !self.mask.is_empty() && self.mask.len() != self.image.len() {
            return Err(RecoverError::InvalidParameter(
                "give one mask per image, or none".into(),
            ));
        }
        Ok(())
    }

    /// The checked observation of image `i`, and its photograph.
    fn observation(&self, i: usize, options: &FunctionalOptions) -> Result<(Observation, Photo)> {
        let scene_path = &self.scene[if self.scene.len() == 1 { 0 } else { i }];
        let scene = RecoveryScene::load(scene_path).map_err(|e| match e {
            RecoverError::Scene(m) => RecoverError::Scene(format!("{}: {m}", scene_path.display())),
            other => other,
        })?;
        let mut photo = Photo::read(&self.image[i])?;
        if let Some(s) = self.saturation {
            photo = photo.with_saturation(s);
        }
        let mask = match self.mask.get(i) {
            Some(m) => Some(crate::photo::read_mask_for(m, &photo)?),
            None => None,
        };
        let functionals = Functionals::build(&scene, options)?;
        let dark_background = scene.scene.environment.is_none();
        let observation =
            Observation::checked(i, functionals, &photo, mask.as_deref(), dark_background)?;
        Ok((observation, photo))
    }

    /// Recovers the table, writes it (and the report with its comparison images, when asked).
    pub fn run(&self) -> Result<RecoverReport> {
        let t0 = Instant::now();
        self.check_counts()?;
        let family = Family::parse(&self.family)?;
        if family != Family::Pca && self.corpus.is_empty() {
            return Err(RecoverError::InvalidParameter(format!(
                "--family {} needs the corpus to combine (--corpus)",
                self.family
            )));
        }
        let model = reduce::Model::load(&self.model)?;
        crate::fit::check_model_grid(&model)?;
        let options = FunctionalOptions {
            env_samples: self.env_samples,
            stride: self.stride,
            ..Default::default()
        };
        let (observations, photos): (Vec<_>, Vec<_>) = (0..self.image.len())
            .map(|i| self.observation(i, &options))
            .collect::<Result<Vec<_>>>()?
            .into_iter()
            .unzip();
        let components = if self.k == 0 {
            let ks = [10, 20, 30, 45, 60]
                .into_iter()
                .filter(|&k| k <= model.components())
                .collect();
            Components::CrossValidate(ks)
        } else {
            Components::Fixed(self.k)
        };
        let recover_options = RecoverOptions {
            components,
            fit: FitOptions {
                prior_weight: self.prior,
                ..Default::default()
            },
            ..Default::default()
        };
        let corpus = if family == Family::Pca {
            None
        } else {
            Some(reduce::Corpus::load(&self.corpus)?)
        };
        let combination_options = CombinationOptions::default();
        let mut family_scores = None;
        // With `auto` the PCA fit is made for its score; kept if it wins.
        let mut pca_recovery = None;
        let use_combination = match (&corpus, family) {
            (Some(c), Family::Auto) => {
                let folds = crate::block_folds(&observations);
                let comb =
                    cross_validate_combination(c, &observations, &combination_options, &folds)?;
                let pca_options = RecoverOptions {
                    components: match &recover_options.components {
                        Components::Fixed(k) => Components::CrossValidate(vec![*k]),
                        other => other.clone(),
                    },
                    ..recover_options.clone()
                };
                let pca = recover(&model, &observations, &pca_options)?;
                let held = pca
                    .cross_validation
                    .iter()
                    .find(|s| s.k == pca.k)
                    .map_or(f64::INFINITY, |s| s.held_out);
                family_scores = Some(FamilyScores {
                    pca: held,
                    combination: comb,
                });
                pca_recovery = Some(pca);
                comb < held
            }
            (Some(_), _) => true,
            (None, _) => false,
        };
        if let (true, Some(c)) = (use_combination, &corpus) {
            let found = fit_combination(c, &observations, &combination_options)?;
            let predictions: Vec<Vec<[f64; 3]>> = observations
                .iter()
                .map(|o| o.functionals.apply_table(&found.table))
                .collect();
            let table = found
                .table
                .clone()
                .with_name(format!("recovered from {} image(s)", self.image.len()));
            brdf::merl::write(&self.out, &table)?;
            let images =
                self.image_reports(&observations, &photos, &predictions, &found.residual_rms)?;
            let report = RecoverReport {
                model: self.model.clone(),
                family: "combination".into(),
                family_scores,
                combination: found
                    .used(c.names())
                    .into_iter()
                    .map(|(n, v)| CombinationTerm {
                        material: n.to_string(),
                        coefficient: v,
                    })
                    .collect(),
                k: 0,
                coefficients: Vec::new(),
                uncertainty: Vec::new(),
                residual_scale: 0.0,
                iterations: 0,
                images,
                bins_constrained: constrained(&observations),
                cross_validation: Vec::new(),
                max_directional_albedo: found.max_albedo,
                albedo_scale: found.albedo_scale,
                nearest_corpus_materials: Vec::new(),
                seconds: t0.elapsed().as_secs_f64(),
            };
            return self.write_report(report);
        }
        let rec = match pca_recovery {
            Some(r) => r,
            None => recover(&model, &observations, &recover_options)?,
        };
        let table = rec
            .table
            .clone()
            .with_name(format!("recovered from {} image(s)", self.image.len()));
        brdf::merl::write(&self.out, &table)?;
        let images = self.image_reports(
            &observations,
            &photos,
            &rec.predictions,
            &rec.fit.residual_rms,
        )?;
        let report = RecoverReport {
            model: self.model.clone(),
            family: "pca".into(),
            family_scores,
            combination: Vec::new(),
            k: rec.k,
            coefficients: rec.fit.coefficients.clone(),
            uncertainty: rec.fit.uncertainty.clone(),
            residual_scale: rec.fit.sigma,
            iterations: rec.fit.iterations,
            images,
            bins_constrained: constrained(&observations),
            cross_validation: rec.cross_validation.clone(),
            max_directional_albedo: rec.max_albedo,
            albedo_scale: rec.albedo_scale,
            nearest_corpus_materials: rec.ranking.iter().take(10).cloned().collect(),
            seconds: t0.elapsed().as_secs_f64(),
        };
        self.write_report(report)
    }

    /// The per-image part of the report, with the side-by-side PNGs when a report is asked for.
    fn image_reports(
        &self,
        observations: &[Observation],
        photos: &[Photo],
        predictions: &[Vec<[f64; 3]>],
        residual_rms: &[f64],
    ) -> Result<Vec<ImageReport>> {
        let mut images = Vec::new();
        for (i, (o, photo)) in observations.iter().zip(photos).enumerate() {
            let comparison_png = match &self.report {
                Some(report) => {
                    let png = side_png(report, i);
                    let (img, exposure) =
                        crate::comparison_image(photo, &o.functionals, &predictions[i])?;
                    let tonemap = render::Tonemap {
                        exposure,
                        operator: render::TonemapOperator::Clamp,
                    };
                    img.write_png(&png, &tonemap)?;
                    Some(png)
                }
                None => None,
            };
            images.push(ImageReport {
                image: self.image[i].clone(),
                pixels_used: o.fitted_pixels(),
                residual_rms_log: residual_rms[i],
                comparison_png,
            });
        }
        Ok(images)
    }

    /// Writes the report JSON when asked for, and returns the report.
    fn write_report(&self, report: RecoverReport) -> Result<RecoverReport> {
        if let Some(path) = &self.report {
            let json = serde_json::to_vec_pretty(&report)
                .map_err(|e| RecoverError::InvalidParameter(format!("report JSON: {e}")))?;
            brdf::write_atomic(path, &json)?;
        }
        Ok(report)
    }
}

/// Number of MERL bins the observations constrain.
fn constrained(observations: &[Observation]) -> usize {
    Observation::constrained_bins(observations)
        .iter()
        .filter(|&&b| b)
        .count()
}
