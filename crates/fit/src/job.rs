//! The job behind `gantry fit`.

use std::collections::BTreeMap;
use std::fmt;
use std::path::PathBuf;

use serde::Serialize;

use crate::error::{FitError, Result};
use crate::study::{markdown_summary, study_corpus, write_csv, StudyOptions, StudyRow};
use crate::{fit, Errors, EvalRows, Exclusions, FitData, FitOptions, ModelKind, Objective, Subset};

/// Seed of the random bin subset (`bins`).
const SUBSET_SEED: u64 = 7;

/// Fit an analytic model to a material, or compare every model across a corpus: the job behind
/// `gantry fit` (with the `cli` feature the options are also the command's arguments).
///
/// # Examples
///
/// ```
/// use fit::{FitJob, FitReport};
/// let job = FitJob {
///     spec: Some("ggx:alpha=0.2,kd=0.1".into()),
///     model: "ggx".into(),
///     lobes: 1,
///     objective: "log".into(),
///     bins: Some(1500),
///     starts: 1,
///     json: false,
///     corpus: Vec::new(),
///     out: "study.csv".into(), // only written by a corpus study
/// };
/// let FitReport::Single(single) = job.run(&mut |_, _, _| {}).unwrap() else {
///     panic!("one material gives one fit");
/// };
/// assert_eq!((single.model, single.objective, single.rows), ("ggx", "log", 1500));
/// // GGX fitted to GGX: the roughness comes back and the error is small on every bin.
/// let alpha = single.parameters["alpha"];
/// assert!((alpha - 0.2).abs() < 0.02, "alpha {alpha}");
/// assert!(single.errors.log < 0.05, "{:?}", single.errors);
/// assert!(brdf::load(&single.spec).is_ok());
/// ```
#[derive(Debug, Clone)]
#[cfg_attr(feature = "cli", derive(clap::Args))]
pub struct FitJob {
    /// Material spec to fit (e.g. merl:nickel, a .binary file).
    pub spec: Option<String>,
    /// Model: lambert, oren-nayar, blinn, phong, ward, lafortune, lafortune-rgb (the thesis's
    /// per-channel form), cook-torrance, ggx,
    /// ashikhmin-shirley (with --corpus: a comma-separated list or `all`).
    #[cfg_attr(feature = "cli", arg(long, alias = "models", default_value = "ggx"))]
    pub model: String,
    /// Specular lobes (2 for lafortune, cook-torrance, ggx).
    #[cfg_attr(feature = "cli", arg(long, default_value_t = 1))]
    pub lobes: usize,
    /// Objective: log (thesis §3.7), ngan (cosine-weighted L2), sphere (rendered sphere).
    #[cfg_attr(feature = "cli", arg(long, default_value = "log"))]
    pub objective: String,
    /// Fit on this many seeded random bins instead of every valid bin (the thesis used 2000).
    #[cfg_attr(feature = "cli", arg(long))]
    pub bins: Option<usize>,
    /// Number of starts of the multi-start.
    #[cfg_attr(feature = "cli", arg(long, default_value_t = 4))]
    pub starts: usize,
    /// Print the result as JSON.
    #[cfg_attr(feature = "cli", arg(long))]
    pub json: bool,
    /// Run the study on every material of a corpus: material specs, folders of neural-BRDF
    /// weights and/or .binary files, or corpus stores (see `gantry forms`).
    #[cfg_attr(feature = "cli", arg(long, num_args = 1..))]
    pub corpus: Vec<String>,
    /// Study CSV output.
    #[cfg_attr(feature = "cli", arg(long, default_value = "study.csv"))]
    pub out: PathBuf,
}

/// One material's fit (the `--json` output).
#[derive(Debug, Clone, Serialize)]
pub struct SingleFit {
    /// The material spec.
    pub material: String,
    /// The model's name.
    pub model: &'static str,
    /// The objective's name.
    pub objective: &'static str,
    /// The fitted parameters by name.
    pub parameters: BTreeMap<String, f64>,
    /// The same in the model's own order (how the text report lists them).
    #[serde(skip)]
    pub ordered_parameters: Vec<(String, f64)>,
    /// The objective's value at the optimum.
    pub fit_error: f64,
    /// Errors of the fit on every valid bin, by each objective.
    pub errors: Errors,
    /// Whether the best start converged.
    pub converged: bool,
    /// Index of the best start.
    pub best_start: usize,
    /// Every start's outcome.
    pub starts: Vec<crate::solve::StartOutcome>,
    /// Rows fitted.
    pub rows: usize,
    /// Bins left out, and why.
    pub exclusions: Exclusions,
    /// The fitted material as a spec string.
    pub spec: String,
}

impl fmt::Display for SingleFit {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let x = &self.exclusions;
        writeln!(
            f,
            "{}: {} fitted with the {} objective on {} rows ({} valid bins, {} missing, {} non-finite)",
            self.material, self.model, self.objective, self.rows, x.valid, x.missing, x.non_finite
        )?;
        for (k, v) in &self.ordered_parameters {
            writeln!(f, "  {k:<10} {v:.6}")?;
        }
        let e = &self.errors;
        writeln!(
            f,
            "errors on every valid bin: log {:.2} %, ngan {:.2} %, sphere {:.2} %",
            100.0 * e.log,
            100.0 * e.ngan,
            100.0 * e.sphere
        )?;
        writeln!(
            f,
            "converged: {}, best start: {} of {}",
            self.converged,
            self.best_start,
            self.starts.len()
        )?;
        write!(f, "{}", self.spec)
    }
}

/// The model comparison over a corpus.
#[derive(Debug, Clone, Serialize)]
pub struct StudyReport {
    /// One row per material and model.
    pub rows: Vec<StudyRow>,
    /// The CSV written.
    pub out: PathBuf,
}

impl fmt::Display for StudyReport {
    /// The rows written and the per-model summary in Markdown.
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        writeln!(
            f,
            "{} fits written to {}",
            self.rows.len(),
            self.out.display()
        )?;
        write!(f, "{}", markdown_summary(&self.rows))
    }
}

/// What [`FitJob::run`] did.
#[derive(Debug, Clone, Serialize)]
#[serde(untagged)]
pub enum FitReport {
    /// One material.
    Single(Box<SingleFit>),
    /// A corpus.
    Study(StudyReport),
}

impl fmt::Display for FitReport {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            FitReport::Single(s) => s.fmt(f),
            FitReport::Study(s) => s.fmt(f),
        }
    }
}

impl FitJob {
    fn subset(&self) -> Subset {
        self.bins.map_or(Subset::All, |bins| Subset::Random {
            bins,
            seed: SUBSET_SEED,
        })
    }

    /// Fits the material, or runs the study over the corpus (writing the CSV after every
    /// material, so an interrupted study keeps its rows); `progress` is told of each finished
    /// material: `(done, of, name)`.
    pub fn run(&self, progress: &mut dyn FnMut(usize, usize, &str)) -> Result<FitReport> {
        match (&self.spec, self.corpus.is_empty()) {
            (Some(spec), true) => Ok(FitReport::Single(Box::new(self.single(spec)?))),
            (None, false) => Ok(FitReport::Study(self.study(progress)?)),
            _ => Err(FitError::Option(
                "give either a material spec or a corpus".into(),
            )),
        }
    }

    fn single(&self, spec: &str) -> Result<SingleFit> {
        let kind = ModelKind::parse(&self.model, self.lobes)?;
        let objective = Objective::parse(&self.objective)?;
        let table = brdf::load(spec)?.tabulate();
        let data = FitData::new(&table)?;
        let options = FitOptions {
            objective,
            subset: self.subset(),
            starts: self.starts,
            ..FitOptions::default()
        };
        let r = fit(kind, &data, &options)?;
        let errors = EvalRows::new(&data)?.errors(&r.model);
        Ok(SingleFit {
            material: spec.to_string(),
            model: kind.name(),
            objective: objective.name(),
            parameters: r.model.named().into_iter().collect(),
            ordered_parameters: r.model.named(),
            fit_error: r.fit_error,
            errors,
            converged: r.converged,
            best_start: r.best_start,
            spec: r.spec(),
            starts: r.starts,
            rows: r.rows,
            exclusions: data.exclusions,
        })
    }

    fn study(&self, progress: &mut dyn FnMut(usize, usize, &str)) -> Result<StudyReport> {
        let mut options = StudyOptions::default();
        if self.model != "all" {
            options.models = self
                .model
                .split(',')
                .map(|m| ModelKind::parse(m.trim(), self.lobes))
                .collect::<Result<_>>()?;
        }
        options.fit.starts = self.starts;
        if self.bins.is_some() {
            options.fit.subset = self.subset();
        }
        let sources = brdf::sources(&self.corpus)?;
        let names: Vec<String> = sources.iter().map(|s| s.name()).collect();
        if names.is_empty() {
            return Err(FitError::NoData(format!(
                "no materials in {}",
                self.corpus.join(" ")
            )));
        }
        let rows = study_corpus(
            &names,
            |i| -> Result<brdf::MerlTable> { Ok(sources[i].table()?) },
            &options,
            |k, rows| {
                write_csv(rows, &self.out)?;
                progress(k, names.len(), &names[k - 1]);
                Ok(())
            },
        )?;
        Ok(StudyReport {
            rows,
            out: self.out.clone(),
        })
    }
}
