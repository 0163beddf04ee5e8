//! The trait jobs behind `gantry traits fit|score|path` and `gantry edit`.

use std::fmt;
use std::path::{Path, PathBuf};

use reduce::Model;
use serde::Serialize;

use crate::error::{Result, TraitsError};
use crate::navigate::{
    path_points, Embedding, Navigator, NavigatorOptions, PathKind, Space, TraitSet,
};
use crate::study::SetFit;
use crate::validity::{Check, ValidityReport};
use crate::{FitOptions, LabelSet, Method, RatingSet, RidgeVariant};

/// Fit trait vectors from a label file (binary) or rating file (ridge) on a model.
///
/// # Examples
///
/// The four jobs in turn: fit a trait, score materials with it, walk a path and edit.
///
/// ```
/// use traits::{EditJob, FitJob, PathJob, ScoreJob, Space};
/// // Eight analytic materials, four matte and four glossy, and a 7-component model of them.
/// let mut corpus = reduce::Corpus::new(brdf::MATERIAL_DIM);
/// for i in 0..8 {
///     let spec = if i < 4 {
///         format!("lambert:kd={}", 0.1 + 0.1 * i as f64)
///     } else {
///         format!("ggx:alpha={},kd=0.2,ks=0.1", 0.5 - 0.1 * (i - 4) as f64)
///     };
///     let table = brdf::load(&spec).unwrap().tabulate();
///     corpus.push_values(format!("m{i}"), &table.values()).unwrap();
/// }
/// // The model carries a 2-D chart, the space a process path walks in.
/// let model = reduce::build_model(&corpus, 7, Some(2), None).unwrap();
/// let dir = tempfile::tempdir().unwrap();
/// let path = |name: &str| dir.path().join(name);
/// model.save(path("model.bin")).unwrap();
/// let mut labels = String::from("material,glossy\n");
/// for i in 0..8 {
///     labels += &format!("m{i},{}\n", if i < 4 { -1 } else { 1 });
/// }
/// std::fs::write(path("labels.csv"), labels).unwrap();
///
/// let fitted = FitJob {
///     labels: path("labels.csv"),
///     model: path("model.bin"),
///     space: Space::Linear,
///     method: None, // a file of 1 / -1 cells: binary labels, SVM
///     dim: 5,
///     no_cv: true,
///     out: path("traits.json"),
/// }
/// .run()
/// .unwrap();
/// assert_eq!(fitted.traits, [("glossy".to_string(), None)]);
///
/// let scores = ScoreJob {
///     specs: vec!["m0".into(), "ggx:alpha=0.15,kd=0.2,ks=0.1".into()],
///     traits: path("traits.json"),
///     model: path("model.bin"),
/// }
/// .run()
/// .unwrap();
/// // A material outside the corpus is projected, and scores as glossy as it looks.
/// let (matte, shiny) = (scores.materials[0].1[0], scores.materials[1].1[0]);
/// assert!(matte < 0.5 && shiny > 0.5, "{matte} {shiny}");
///
/// let walked = PathJob {
///     specs: vec!["m2".into(), "m6".into()],
///     model: path("model.bin"),
///     space: Space::Chart,
///     steps: 3,
///     least_squares: false,
///     out: path("path"),
/// }
/// .run()
/// .unwrap();
/// assert_eq!(walked.steps.len(), 3);
/// for step in &walked.steps {
///     // Only valid points are written.
///     assert_eq!(step.file.is_some(), step.failed.is_empty() && step.max_albedo <= 1.0);
///     if let Some(file) = &step.file {
///         assert!(path("path").join(file).exists());
///     }
/// }
/// assert!(path("path").join("path.csv").exists());
///
/// let edited = EditJob {
///     spec: "m1".into(),
///     traits: path("traits.json"),
///     model: path("model.bin"),
///     add: vec!["glossy=0.5".into()],
///     hull: false,
///     out: path("edited.binary"),
/// }
/// .run()
/// .unwrap();
/// assert!(edited.validity.is_valid());
/// assert!((0.0..=1.0).contains(&edited.fraction_applied));
/// let (_, before, after) = edited.scores[0];
/// assert!((after - before - 0.5 * edited.fraction_applied).abs() < 1e-9);
/// let table = brdf::merl::read(path("edited.binary")).unwrap();
/// assert!(table.values().iter().all(|v| *v >= 0.0));
/// ```
#[derive(Debug, Clone)]
#[cfg_attr(feature = "cli", derive(clap::Args))]
pub struct FitJob {
    /// Label CSV (1 / -1 / empty) for mean, fisher, svm; rating CSV ([0, 1]) for ridge.
    #[cfg_attr(feature = "cli", arg(long))]
    pub labels: PathBuf,
    /// Model file (`gantry model build`).
    #[cfg_attr(feature = "cli", arg(long))]
    pub model: PathBuf,
    /// linear or chart.
    #[cfg_attr(feature = "cli", arg(long, default_value = "linear"))]
    pub space: Space,
    /// mean, fisher, svm or ridge [default: svm for a label file, ridge for a rating file].
    #[cfg_attr(feature = "cli", arg(long))]
    pub method: Option<Method>,
    /// PCA coordinates of the linear space.
    #[cfg_attr(feature = "cli", arg(long, default_value_t = crate::navigate::LINEAR_DIM))]
    pub dim: usize,
    /// Skip the leave-one-out agreement.
    #[cfg_attr(feature = "cli", arg(long))]
    pub no_cv: bool,
    /// Output JSON.
    #[cfg_attr(feature = "cli", arg(long))]
    pub out: PathBuf,
}

/// What [`FitJob::run`] did: the leave-one-out agreement of each trait, and where the set went.
#[derive(Debug, Clone, Serialize)]
pub struct FitReport {
    /// The method fitted (chosen from the file when none was given).
    pub method: Method,
    /// `(trait, leave-one-out agreement)`; `None` when cross-validation was skipped. For rated
    /// traits fitted by the default selection it is the nested leave-one-out Spearman ρ.
    pub traits: Vec<(String, Option<f64>)>,
    /// The ridge variant each rated trait chose (empty for binary traits and fixed penalties).
    pub variants: Vec<Option<RidgeVariant>>,
    /// The trait set file written.
    pub out: PathBuf,
}

impl fmt::Display for FitReport {
    /// CSV: `trait,cross_validated`, one row per trait; with `,dims,lambda` (the chosen ridge
    /// variant) when the traits were selected.
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let selected = self.variants.iter().any(Option::is_some);
        write!(f, "trait,cross_validated")?;
        if selected {
            write!(f, ",dims,lambda")?;
        }
        for (i, (name, cv)) in self.traits.iter().enumerate() {
            write!(f, "\n{name},")?;
            if let Some(v) = cv {
                write!(f, "{v:.3}")?;
            }
            if selected {
                match self.variants.get(i).copied().flatten() {
                    Some(v) => write!(f, ",{},{}", v.dims, v.lambda)?,
                    None => write!(f, ",,")?,
                }
            }
        }
        Ok(())
    }
}

/// Print the trait scores of materials as CSV.
///
/// # Examples
///
/// The example on [`FitJob`] runs all four trait jobs, this one included.
#[derive(Debug, Clone)]
#[cfg_attr(feature = "cli", derive(clap::Args))]
pub struct ScoreJob {
    /// Material specs (corpus names are looked up in the model directly).
    #[cfg_attr(feature = "cli", arg(required = true))]
    pub specs: Vec<String>,
    /// Trait set JSON.
    #[cfg_attr(feature = "cli", arg(long))]
    pub traits: PathBuf,
    /// Model file.
    #[cfg_attr(feature = "cli", arg(long))]
    pub model: PathBuf,
}

/// The scores [`ScoreJob::run`] computed.
#[derive(Debug, Clone, Serialize)]
pub struct ScoreReport {
    /// Trait names, the columns.
    pub traits: Vec<String>,
    /// `(material spec, one score per trait)`.
    pub materials: Vec<(String, Vec<f64>)>,
}

impl fmt::Display for ScoreReport {
    /// CSV: `material,<trait>...`, scores to four decimals.
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "material,{}", self.traits.join(","))?;
        for (spec, scores) in &self.materials {
            write!(f, "\n{spec}")?;
            for s in scores {
                write!(f, ",{s:.4}")?;
            }
        }
        Ok(())
    }
}

/// Interpolate along a path of materials and write the valid tables.
///
/// # Examples
///
/// The example on [`FitJob`] runs all four trait jobs, this one included.
#[derive(Debug, Clone)]
#[cfg_attr(feature = "cli", derive(clap::Args))]
pub struct PathJob {
    /// Two or more material specs along the path.
    #[cfg_attr(feature = "cli", arg(required = true, num_args = 2..))]
    pub specs: Vec<String>,
    /// Model file.
    #[cfg_attr(feature = "cli", arg(long))]
    pub model: PathBuf,
    /// linear or chart.
    #[cfg_attr(feature = "cli", arg(long, default_value = "chart"))]
    pub space: Space,
    /// Points along the path.
    #[cfg_attr(feature = "cli", arg(long, default_value_t = 8))]
    pub steps: usize,
    /// Least-squares line instead of the piecewise path.
    #[cfg_attr(feature = "cli", arg(long))]
    pub least_squares: bool,
    /// Output directory (step-NN.binary and path.csv).
    #[cfg_attr(feature = "cli", arg(long))]
    pub out: PathBuf,
}

/// One point of a process path.
#[derive(Debug, Clone, Serialize)]
pub struct PathStep {
    /// The table file written, when the point is valid.
    pub file: Option<String>,
    /// Checks the point fails.
    pub failed: Vec<Check>,
    /// The largest directional albedo of the back-projected table.
    pub max_albedo: f64,
}

/// What [`PathJob::run`] wrote (`path.csv` holds the same).
#[derive(Debug, Clone, Serialize)]
pub struct PathReport {
    /// The points, in order.
    pub steps: Vec<PathStep>,
}

impl PathReport {
    fn csv(&self) -> String {
        let mut csv = String::from("step,file,valid,failed,max_albedo\n");
        for (i, s) in self.steps.iter().enumerate() {
            csv.push_str(&format!(
                "{i},{},{},{:?},{:.4}\n",
                s.file.as_deref().unwrap_or(""),
                s.file.is_some(),
                s.failed,
                s.max_albedo
            ));
        }
        csv
    }
}

impl fmt::Display for PathReport {
    /// One line per step: whether it was valid and written.
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        for (i, s) in self.steps.iter().enumerate() {
            if i > 0 {
                writeln!(f)?;
            }
            let state = if s.file.is_some() {
                "valid, written"
            } else {
                "invalid, not written"
            };
            write!(f, "step {i}: {state}")?;
        }
        Ok(())
    }
}

/// Edit a material along trait vectors, stopping at the border of the valid set.
///
/// # Examples
///
/// The example on [`FitJob`] runs all four trait jobs, this one included.
#[derive(Debug, Clone)]
#[cfg_attr(feature = "cli", derive(clap::Args))]
pub struct EditJob {
    /// Material spec to start from.
    pub spec: String,
    /// Trait set JSON.
    #[cfg_attr(feature = "cli", arg(long))]
    pub traits: PathBuf,
    /// Model file.
    #[cfg_attr(feature = "cli", arg(long))]
    pub model: PathBuf,
    /// `trait=amount` (trait units: 1 = from the average material without it to the average
    /// with it). Repeatable; all are applied as one move.
    #[cfg_attr(feature = "cli", arg(long = "add", required = true))]
    pub add: Vec<String>,
    /// Also keep the point inside the convex hull of the corpus.
    #[cfg_attr(feature = "cli", arg(long))]
    pub hull: bool,
    /// Output MERL .binary file.
    #[cfg_attr(feature = "cli", arg(long))]
    pub out: PathBuf,
}

/// What [`EditJob::run`] did.
#[derive(Debug, Clone, Serialize)]
pub struct EditReport {
    /// Share of the requested move applied (1 when nothing stopped it).
    pub fraction_applied: f64,
    /// The check that stopped the move short, if any.
    pub stopped_by: Option<Check>,
    /// Validity of the written table.
    pub validity: ValidityReport,
    /// Values of the back-projection below zero, written as 0 (each less than the model's
    /// floor below).
    pub clamped: usize,
    /// `(trait, score before, score after)`.
    pub scores: Vec<(String, f64, f64)>,
    /// The table file written.
    pub out: PathBuf,
}

impl fmt::Display for EditReport {
    /// The applied share, the validity report as JSON and each trait's score before and after.
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(
            f,
            "moved {:.1} % of the requested edit",
            100.0 * self.fraction_applied
        )?;
        if let Some(c) = self.stopped_by {
            write!(f, ", stopped at the border by {c}")?;
        }
        if self.clamped > 0 {
            write!(f, "; {} values just below zero written as 0", self.clamped)?;
        }
        let json = serde_json::to_string_pretty(&self.validity).map_err(|_| fmt::Error)?;
        write!(f, "\n{json}")?;
        for (name, before, after) in &self.scores {
            write!(f, "\nscore {name}: {before:.3} -> {after:.3}")?;
        }
        Ok(())
    }
}

fn load_model(path: &Path) -> Result<Model> {
    Ok(Model::load(path)?)
}

/// Coordinates of a material spec: a corpus name directly, anything else projected.
pub fn coords_of(embedding: &Embedding, spec: &str) -> Result<Vec<f64>> {
    let name = spec.strip_prefix("merl:").unwrap_or(spec);
    if embedding.model.names.iter().any(|n| n == name) {
        return embedding.of_name(name);
    }
    let table = brdf::load(spec)?.tabulate();
    embedding.project_values(&table.values())
}

/// A label file and the binary method to fit it with, or a rating file (ridge).
enum Labels {
    Binary(LabelSet, Method),
    Graded(RatingSet),
}

impl FitJob {
    /// Reads the labels as the method needs them; without a method, a file of 1 / -1 / empty
    /// cells is a label file (SVM) and a file of values in [0, 1] a rating file (ridge).
    fn read_labels(&self) -> Result<Labels> {
        let path = &self.labels;
        let text = std::fs::read_to_string(path).map_err(|e| TraitsError::io(path, e))?;
        match self.method {
            Some(Method::Ridge) => Ok(Labels::Graded(RatingSet::parse(&text, path)?)),
            Some(method) => match LabelSet::parse(&text, path) {
                Ok(labels) => Ok(Labels::Binary(labels, method)),
                Err(e) if RatingSet::parse(&text, path).is_ok() => {
                    Err(TraitsError::InvalidParameter(format!(
                        "{e}: this is a rating file, which only the ridge method fits (leave \
                         the method out, or give ridge)"
                    )))
                }
                Err(e) => Err(e),
            },
            None => match LabelSet::parse(&text, path) {
                Ok(labels) => Ok(Labels::Binary(labels, Method::Svm)),
                Err(e) => RatingSet::parse(&text, path)
                    .map(Labels::Graded)
                    .map_err(|_| e),
            },
        }
    }

    /// Fits the trait vectors of a label or rating file and writes the trait set.
    pub fn run(&self) -> Result<FitReport> {
        let model = load_model(&self.model)?;
        let embedding = Embedding::new(&model, self.space, self.dim)?;
        let coords = embedding.corpus()?;
        let fit = SetFit {
            coords: &coords,
            names: &model.names,
            space: self.space,
            options: FitOptions::default(),
            cross_validate: !self.no_cv,
        };
        let set = match self.read_labels()? {
            Labels::Binary(labels, method) => fit.binary(&labels, method)?,
            Labels::Graded(ratings) => fit.ratings(&ratings)?,
        };
        set.save(&self.out)?;
        Ok(FitReport {
            method: set.method,
            traits: set
                .traits
                .iter()
                .map(|t| (t.name.clone(), t.cross_validated))
                .collect(),
            variants: set.traits.iter().map(|t| t.variant).collect(),
            out: self.out.clone(),
        })
    }
}

impl ScoreJob {
    /// Scores materials on every trait of a set.
    pub fn run(&self) -> Result<ScoreReport> {
        let model = load_model(&self.model)?;
        let set = TraitSet::load(&self.traits)?;
        let embedding = Embedding::new(&model, set.space, set.dim)?;
        let materials = self
            .specs
            .iter()
            .map(|s| {
                let x = coords_of(&embedding, s)?;
                let scores = set.traits.iter().map(|t| t.direction.score(&x)).collect();
                Ok((s.clone(), scores))
            })
            .collect::<Result<_>>()?;
        Ok(ScoreReport {
            traits: set.traits.iter().map(|t| t.name.clone()).collect(),
            materials,
        })
    }
}

impl PathJob {
    /// Walks a process path (thesis §5.4), writing each valid point's table and `path.csv`.
    pub fn run(&self) -> Result<PathReport> {
        let model = load_model(&self.model)?;
        let nav = Navigator::new(&model, self.space, NavigatorOptions::default())?;
        let points = self
            .specs
            .iter()
            .map(|s| coords_of(&nav.embedding, s))
            .collect::<Result<Vec<_>>>()?;
        let kind = if self.least_squares {
            PathKind::LeastSquares
        } else {
            PathKind::Piecewise
        };
        std::fs::create_dir_all(&self.out).map_err(|e| TraitsError::io(&self.out, e))?;
        let mut steps = Vec::new();
        for (i, x) in path_points(&points, self.steps, kind)?.iter().enumerate() {
            let state = nav.state(x)?;
            let failed = nav.failures(&state)?;
            let (table, report) = nav.table(&state)?;
            let file =
                (failed.is_empty() && report.is_valid()).then(|| format!("step-{i:02}.binary"));
            if let Some(file) = &file {
                brdf::merl::write(self.out.join(file), &table)?;
            }
            steps.push(PathStep {
                file,
                failed,
                max_albedo: report.max_albedo.0,
            });
        }
        let report = PathReport { steps };
        brdf::write_atomic(&self.out.join("path.csv"), report.csv().as_bytes())?;
        Ok(report)
    }
}

/// Parses an `--add` argument `trait=amount`.
fn parse_addition(kv: &str) -> Result<(&str, f64)> {
    let bad = || TraitsError::InvalidParameter(format!("--add {kv:?}: expected trait=amount"));
    let (k, v) = kv.split_once('=').ok_or_else(bad)?;
    let amount: f64 = v.trim().parse().map_err(|_| bad())?;
    if !amount.is_finite() {
        return Err(bad());
    }
    Ok((k.trim(), amount))
}

impl EditJob {
    /// Moves a material along trait vectors as one edit and writes the resulting table.
    pub fn run(&self) -> Result<EditReport> {
        let model = load_model(&self.model)?;
        let set = TraitSet::load(&self.traits)?;
        let options = NavigatorOptions {
            convex_hull: self.hull,
            linear_dim: set.dim,
            ..Default::default()
        };
        let nav = Navigator::new(&model, set.space, options)?;
        let x = coords_of(&nav.embedding, &self.spec)?;
        let edits = self
            .add
            .iter()
            .map(|kv| {
                let (name, amount) = parse_addition(kv)?;
                Ok((set.get(name)?, amount))
            })
            .collect::<Result<Vec<_>>>()?;
        let out = nav.edit_many(&x, &edits)?;
        brdf::merl::write(&self.out, &out.table)?;
        Ok(EditReport {
            fraction_applied: if out.requested != 0.0 {
                out.applied / out.requested
            } else {
                1.0
            },
            stopped_by: out.stopped_by,
            clamped: out.clamped,
            validity: out.report,
            scores: set
                .traits
                .iter()
                .map(|t| {
                    (
                        t.name.clone(),
                        t.direction.score(&x),
                        t.direction.score(&out.coords),
                    )
                })
                .collect(),
            out: self.out.clone(),
        })
    }
}

/// Fewest rated materials for the default rating traits.
pub const MIN_RATED: usize = 10;

/// The trait sets an editor starts with on a model, with nothing given but the model:
///
/// 1. the thesis's 16 traits ([`crate::thesis_labels`], SVM) in the linear space;
/// 2. the shared human ratings ([`crate::serrano_ratings_path`], ridge with each trait's
///    variant chosen by leave-one-out) in the linear space, when the file is there;
/// 3. the thesis's traits in the chart, when the model has one.
///
/// Labels and ratings of materials outside the model's corpus are ignored; a trait left with
/// fewer than [`crate::MIN_PER_CLASS`] materials of a class (or [`MIN_RATED`] ratings) is
/// left out, and a set left with no trait is not made. The linear space has
/// 45 coordinates (the default of `gantry traits fit --dim`) or the model's components, whichever is fewer.
/// `cross_validate` adds each trait's leave-one-out agreement.
pub fn default_trait_sets(model: &Model, cross_validate: bool) -> Result<Vec<TraitSet>> {
    let labels = crate::thesis_labels().restricted(&model.names, |l, t| {
        let (present, absent) = l.counts(t);
        present >= crate::MIN_PER_CLASS && absent >= crate::MIN_PER_CLASS
    });
    let ratings = match RatingSet::load(crate::serrano_ratings_path()) {
        Ok(r) => Some(r.restricted(&model.names, |r, t| {
            r.column(t).iter().filter(|(_, v)| v.is_some()).count() >= MIN_RATED
        })),
        Err(e) => {
            tracing::info!("no rating traits: {e}");
            None
        }
    };
    let dim = crate::navigate::LINEAR_DIM.min(model.components());
    let mut spaces = vec![Space::Linear];
    if model.chart.is_some() {
        spaces.push(Space::Chart);
    }
    let mut sets = Vec::new();
    for space in spaces {
        let coords = Embedding::new(model, space, dim)?.corpus()?;
        let fit = SetFit {
            coords: &coords,
            names: &model.names,
            space,
            options: FitOptions::default(),
            cross_validate,
        };
        if !labels.traits.is_empty() {
            sets.push(fit.binary(&labels, Method::Svm)?);
        }
        if let (Space::Linear, Some(r)) = (space, &ratings) {
            if !r.traits.is_empty() {
                sets.push(fit.ratings(r)?);
            }
        }
    }
    Ok(sets)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn additions_parse_and_bad_ones_are_refused() {
        assert_eq!(parse_addition("glossy=0.5").unwrap(), ("glossy", 0.5));
        assert_eq!(parse_addition(" red = -1 ").unwrap(), ("red", -1.0));
        for bad in ["glossy", "glossy=", "glossy=x", "glossy=NaN", "glossy=inf"] {
            assert!(
                matches!(parse_addition(bad), Err(TraitsError::InvalidParameter(_))),
                "{bad}"
            );
        }
    }

    /// A model of eight analytic materials, from matte to glossy, and a job on it.
    fn glossiness_job(dir: &Path) -> FitJob {
        let mut corpus = reduce::Corpus::new(brdf::MATERIAL_DIM);
        for i in 0..8 {
            let spec = if i < 4 {
                format!("lambert:kd={}", 0.1 + 0.1 * i as f64)
            } else {
                format!("ggx:alpha={},kd=0.2,ks=0.1", 0.5 - 0.1 * (i - 4) as f64)
            };
            let table = brdf::load(&spec).unwrap().tabulate();
            corpus
                .push_values(format!("m{i}"), &table.values())
                .unwrap();
        }
        let model = reduce::build_model(&corpus, 7, None, None).unwrap();
        model.save(dir.join("model.bin")).unwrap();
        FitJob {
            labels: PathBuf::new(),
            model: dir.join("model.bin"),
            space: Space::Linear,
            method: None,
            dim: 5,
            no_cv: true,
            out: dir.join("traits.json"),
        }
    }

    #[test]
    fn the_method_follows_the_file_unless_given() {
        let dir = tempfile::tempdir().unwrap();
        let job = glossiness_job(dir.path());
        let labels = dir.path().join("labels.csv");
        let ratings = dir.path().join("ratings.csv");
        let (mut l, mut r) = (
            String::from("material,glossy\n"),
            String::from("material,glossy\n"),
        );
        for i in 0..8 {
            l.push_str(&format!("m{i},{}\n", if i < 4 { -1 } else { 1 }));
            r.push_str(&format!("m{i},{}\n", i as f64 / 8.0));
        }
        std::fs::write(&labels, l).unwrap();
        std::fs::write(&ratings, r).unwrap();
        let on = |file: &Path, method| FitJob {
            labels: file.to_path_buf(),
            method,
            ..job.clone()
        };
        assert_eq!(on(&labels, None).run().unwrap().method, Method::Svm);
        let graded = on(&ratings, None).run().unwrap();
        assert_eq!(graded.method, Method::Ridge);
        assert_eq!(TraitSet::load(&job.out).unwrap().method, Method::Ridge);
        assert_eq!(
            on(&labels, Some(Method::Mean)).run().unwrap().method,
            Method::Mean
        );
        // A binary method on graded ratings says what to do instead.
        match on(&ratings, Some(Method::Svm)).run() {
            Err(TraitsError::InvalidParameter(m)) => assert!(m.contains("ridge"), "{m}"),
            other => panic!("{other:?}"),
        }
        // Ridge on a label file: -1 is not a rating.
        assert!(matches!(
            on(&labels, Some(Method::Ridge)).run(),
            Err(TraitsError::Parse { .. })
        ));
    }

    /// Twenty-four materials named after labelled MERL materials (analytic stand-ins: a model
    /// only sees names and values), so some thesis traits keep enough labels; K = 8, a 3-D
    /// chart. Built once.
    fn labelled_analytic_model() -> &'static Model {
        static MODEL: std::sync::OnceLock<Model> = std::sync::OnceLock::new();
        MODEL.get_or_init(|| {
            let names: Vec<String> = crate::thesis_labels()
                .materials
                .iter()
                .take(24)
                .cloned()
                .collect();
            let mut corpus = reduce::Corpus::new(brdf::MATERIAL_DIM);
            for (i, name) in names.iter().enumerate() {
                let spec = format!(
                    "ggx:alpha={},kd={},ks=0.1",
                    0.05 + 0.02 * i as f64,
                    0.05 + 0.01 * (i % 7) as f64
                );
                let table = brdf::load(&spec).unwrap().tabulate();
                corpus.push_values(name.clone(), &table.values()).unwrap();
            }
            reduce::build_model(&corpus, 8, Some(3), None).unwrap()
        })
    }

    #[test]
    fn chart_back_projections_stay_near_the_corpus_range() {
        let model = labelled_analytic_model();
        let mut e = Embedding::new(model, Space::Chart, 8).unwrap();
        let corpus = e.corpus().unwrap();
        let pca = &model.pca.coords;
        let (lo, hi, sd): (Vec<f64>, Vec<f64>, Vec<f64>) = (0..e.pca_dim)
            .map(|j| {
                let c = pca.column(j);
                let m = c.mean();
                let sd = (c.iter().map(|v| (v - m).powi(2)).sum::<f64>() / c.len() as f64).sqrt();
                (c.min(), c.max(), sd)
            })
            .fold((vec![], vec![], vec![]), |mut a, (l, h, s)| {
                a.0.push(l);
                a.1.push(h);
                a.2.push(s);
                a
            });
        let limited = |e: &Embedding, x: &[f64]| e.to_pca(x).unwrap();
        let mut untouched = 0;
        for i in 0..corpus.nrows() {
            let x: Vec<f64> = corpus.row(i).iter().copied().collect();
            let with = limited(&e, &x);
            let mut free = e;
            free.pca_margin = None;
            let without = limited(&free, &x);
            // The corpus's own points are inside the range: untouched.
            let inside = without
                .iter()
                .enumerate()
                .all(|(j, v)| (lo[j] - sd[j]..=hi[j] + sd[j]).contains(v));
            if inside {
                assert_eq!(with, without);
                untouched += 1;
            }
        }
        // (On this 3-D chart of 24 analytic materials about half the corpus points come back
        // inside; on the shared 96-material model all of them do.)
        assert!(untouched > 0, "no corpus point inside");
        // Far outside the corpus, every coefficient is held within range ± one sd.
        let far: Vec<f64> = corpus
            .row(0)
            .iter()
            .map(|v| v + 40.0 * (v.abs() + 1.0))
            .collect();
        e.pca_margin = Some(crate::CHART_PCA_MARGIN);
        let c = limited(&e, &far);
        for (j, v) in c.iter().enumerate() {
            assert!(
                *v >= lo[j] - sd[j] - 1e-9 && *v <= hi[j] + sd[j] + 1e-9,
                "coefficient {j}: {v} outside [{}, {}]",
                lo[j] - sd[j],
                hi[j] + sd[j]
            );
        }
        let mut free = e;
        free.pca_margin = None;
        assert_ne!(
            c,
            limited(&free, &far),
            "the far point was not limited at all"
        );
    }

    #[test]
    fn default_sets_keep_the_traits_the_corpus_can_carry() {
        let model = labelled_analytic_model();
        let labels = crate::thesis_labels();
        let names = &model.names;
        let sets = default_trait_sets(model, false).unwrap();
        // The expected traits, counted here from the label file itself.
        let expected: Vec<&String> = labels
            .traits
            .iter()
            .enumerate()
            .filter(|&(t, _)| {
                let col = labels.column(t);
                let on = |l| {
                    col.iter()
                        .filter(|(m, x)| *x == l && names.iter().any(|n| n == m))
                        .count()
                };
                on(crate::Label::Present) >= crate::MIN_PER_CLASS
                    && on(crate::Label::Absent) >= crate::MIN_PER_CLASS
            })
            .map(|(_, n)| n)
            .collect();
        assert!(!expected.is_empty() && expected.len() < labels.traits.len());
        let binary: Vec<&TraitSet> = sets.iter().filter(|s| s.method == Method::Svm).collect();
        assert_eq!(
            binary.iter().map(|s| s.space).collect::<Vec<_>>(),
            [Space::Linear, Space::Chart]
        );
        for set in &binary {
            let got: Vec<&String> = set.traits.iter().map(|t| &t.name).collect();
            assert_eq!(got, expected);
            assert_eq!(set.dim, if set.space == Space::Linear { 8 } else { 3 });
        }
        // The shared ratings (required: CI has the shared data) rate some of these materials.
        let ratings = RatingSet::load(crate::serrano_ratings_path()).unwrap();
        let rated = |t: usize| {
            ratings
                .column(t)
                .iter()
                .filter(|(m, v)| v.is_some() && names.iter().any(|n| n == m))
                .count()
        };
        let want: Vec<&String> = (0..ratings.traits.len())
            .filter(|&t| rated(t) >= MIN_RATED)
            .map(|t| &ratings.traits[t])
            .collect();
        let graded: Vec<&TraitSet> = sets.iter().filter(|s| s.method == Method::Ridge).collect();
        if want.is_empty() {
            assert!(graded.is_empty());
        } else {
            assert_eq!(graded.len(), 1);
            assert_eq!(graded[0].space, Space::Linear);
            let got: Vec<&String> = graded[0].traits.iter().map(|t| &t.name).collect();
            assert_eq!(got, want);
            assert!(graded[0].traits.iter().all(|t| t.variant.is_some()));
        }
    }

    #[test]
    fn reports_print_the_command_formats() {
        let fit = FitReport {
            method: Method::Svm,
            traits: vec![("glossy".into(), Some(0.81234)), ("red".into(), None)],
            variants: vec![None, None],
            out: "t.json".into(),
        };
        assert_eq!(fit.to_string(), "trait,cross_validated\nglossy,0.812\nred,");
        let rated = FitReport {
            method: Method::Ridge,
            variants: vec![
                Some(RidgeVariant {
                    dims: 5,
                    lambda: 0.01,
                }),
                None,
            ],
            ..fit
        };
        assert_eq!(
            rated.to_string(),
            "trait,cross_validated,dims,lambda\nglossy,0.812,5,0.01\nred,,,"
        );
        let score = ScoreReport {
            traits: vec!["a".into(), "b".into()],
            materials: vec![("m".into(), vec![0.5, -1.25])],
        };
        assert_eq!(score.to_string(), "material,a,b\nm,0.5000,-1.2500");
        let path = PathReport {
            steps: vec![
                PathStep {
                    file: Some("step-00.binary".into()),
                    failed: vec![],
                    max_albedo: 0.5,
                },
                PathStep {
                    file: None,
                    failed: vec![Check::NonNegativity],
                    max_albedo: 1.2,
                },
            ],
        };
        assert_eq!(
            path.to_string(),
            "step 0: valid, written\nstep 1: invalid, not written"
        );
        assert_eq!(
            path.csv(),
            "step,file,valid,failed,max_albedo\n0,step-00.binary,true,[],0.5000\n1,,false,[NonNegativity],1.2000\n"
        );
    }
}
