//! The model jobs behind `gantry model build|reconstruct|report`.

use std::fmt;
use std::path::PathBuf;

use serde::Serialize;

use crate::corpus::Corpus;
use crate::error::Result;
use crate::model::{build_mapped_model, Model, DEFAULT_COMPONENTS};

/// Learn a PCA model (log space) and a chart from a corpus of measured BRDFs: the job behind
/// `gantry model build`.
///
/// Each model job is an options value (with the `cli` feature also the command's arguments), a
/// `run` method and a serde report whose `Display` is what the command prints.
///
/// # Examples
///
/// ```
/// use reduce::{BuildJob, Model};
///
/// let dir = std::env::temp_dir().join(format!("reduce-build-doc-{}", std::process::id()));
/// let job = BuildJob {
///     corpus: vec!["lambert:kd=0.2".into(), "ggx:alpha=0.3".into()],
///     out: dir.join("model.bin"),
///     components: None,
///     chart_dim: 0,
///     mapping: "log".into(),
/// };
/// let report = job.run().unwrap();
/// // two materials leave one direction of variation
/// assert_eq!((report.materials, report.components, report.chart_dim), (2, 1, None));
/// assert_eq!(Model::load(&report.out).unwrap().names, ["lambert:kd=0.2", "ggx:alpha=0.3"]);
/// # std::fs::remove_dir_all(&dir).unwrap();
/// ```
#[derive(Debug, Clone)]
#[cfg_attr(feature = "cli", derive(clap::Args))]
pub struct BuildJob {
    /// Corpus: material specs, folders of neural-BRDF weights and/or .binary files, or corpus
    /// stores (see `gantry forms`).
    #[cfg_attr(feature = "cli", arg(long, num_args = 1.., required = true))]
    pub corpus: Vec<String>,
    /// Output model file.
    #[cfg_attr(feature = "cli", arg(long))]
    pub out: PathBuf,
    /// Number of principal components kept.
    #[cfg_attr(feature = "cli", arg(long))]
    pub components: Option<usize>,
    /// Dimension of the chart (non-linear model); 0 disables charting.
    #[cfg_attr(feature = "cli", arg(long, default_value_t = crate::model::DEFAULT_CHART_DIM))]
    pub chart_dim: usize,
    /// Space of the PCA: `log` (the thesis's), `cosine-log` or `cosine-log:EPSILON` (Nielsen
    /// et al.'s; `capture --fast` and `model reconstruct` take it, the commands that decode
    /// log-space models themselves refuse it).
    #[cfg_attr(feature = "cli", arg(long, default_value = "log"))]
    pub mapping: String,
}

/// What [`BuildJob::run`] built.
#[derive(Debug, Clone, Serialize)]
pub struct BuildReport {
    /// The model file.
    pub out: PathBuf,
    /// Materials of the corpus.
    pub materials: usize,
    /// Principal components kept.
    pub components: usize,
    /// Dimension of the chart, when one was built.
    pub chart_dim: Option<usize>,
}

impl fmt::Display for BuildReport {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(
            f,
            "wrote {} ({} materials, {} components",
            self.out.display(),
            self.materials,
            self.components
        )?;
        if let Some(d) = self.chart_dim {
            write!(f, ", chart of dimension {d}")?;
        }
        write!(f, ")")
    }
}

/// Project a material onto the first K components and write the reconstruction: the job
/// behind `gantry model reconstruct`.
///
/// # Examples
///
/// ```
/// use reduce::{BuildJob, ReconstructJob};
///
/// let dir = std::env::temp_dir().join(format!("reduce-reconstruct-doc-{}", std::process::id()));
/// let model = dir.join("model.bin");
/// BuildJob {
///     corpus: vec!["lambert:kd=0.2".into(), "ggx:alpha=0.3".into()],
///     out: model.clone(),
///     components: None,
///     chart_dim: 0,
///     mapping: "log".into(),
/// }
/// .run()
/// .unwrap();
/// // a corpus member lies on the line through the mean along the one component
/// let report = ReconstructJob {
///     spec: "ggx:alpha=0.3".into(),
///     model,
///     k: 1,
///     out: dir.join("ggx.binary"),
///     encoder: "projection".into(),
/// }
/// .run()
/// .unwrap();
/// assert!(report.relative < 1e-3, "{report}");
/// assert!(brdf::merl::read(&report.out).is_ok());
/// # std::fs::remove_dir_all(&dir).unwrap();
/// ```
#[derive(Debug, Clone)]
#[cfg_attr(feature = "cli", derive(clap::Args))]
pub struct ReconstructJob {
    /// Material spec to project.
    pub spec: String,
    /// Model file.
    #[cfg_attr(feature = "cli", arg(long))]
    pub model: PathBuf,
    /// Number of components used.
    #[cfg_attr(feature = "cli", arg(long))]
    pub k: usize,
    /// Output MERL .binary file.
    #[cfg_attr(feature = "cli", arg(long))]
    pub out: PathBuf,
    /// How the material's coefficients are found: `projection` (the thesis's) or `robust`
    /// (least absolute deviations over a seeded sample of entries).
    #[cfg_attr(feature = "cli", arg(long, default_value = "projection"))]
    pub encoder: String,
}

/// What [`ReconstructJob::run`] measured of the reconstruction.
#[derive(Debug, Clone, Serialize)]
pub struct ReconstructReport {
    /// The reconstructed table.
    pub out: PathBuf,
    /// Components used.
    pub k: usize,
    /// `‖y − ỹ‖ / ‖y − m‖` in log space.
    pub relative: f64,
    /// RMS error in natural-log units.
    pub rms_log: f64,
}

impl fmt::Display for ReconstructReport {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(
            f,
            "wrote {}: k = {}, relative error {:.4}, RMS log error {:.4}",
            self.out.display(),
            self.k,
            self.relative,
            self.rms_log
        )
    }
}

/// Write the eigenvalue and error curves (PNG plots and CSV) of a model: the job behind
/// `gantry model report` (see [`write_report`](crate::write_report) for the files).
///
/// # Examples
///
/// ```
/// use reduce::{build_model, Corpus, ReportJob};
///
/// let dir = std::env::temp_dir().join(format!("reduce-report-doc-{}", std::process::id()));
/// // a model of four small synthetic materials
/// let mut corpus = Corpus::new(30);
/// for i in 0..4 {
///     let values: Vec<f64> = (0..30).map(|d| 0.05 * (1 + (i + 2) * d % 7) as f64).collect();
///     corpus.push_values(format!("m{i}"), &values).unwrap();
/// }
/// std::fs::create_dir_all(&dir).unwrap();
/// build_model(&corpus, 3, None, None).unwrap().save(dir.join("model.bin")).unwrap();
/// let written = ReportJob { model: dir.join("model.bin"), out: dir.join("report") }.run().unwrap();
/// let csv = std::fs::read_to_string(written.out.join("eigenvalues.csv")).unwrap();
/// assert!(csv.lines().count() > 1);
/// # std::fs::remove_dir_all(&dir).unwrap();
/// ```
#[derive(Debug, Clone)]
#[cfg_attr(feature = "cli", derive(clap::Args))]
pub struct ReportJob {
    /// Model file.
    pub model: PathBuf,
    /// Output directory for plots and CSV files.
    #[cfg_attr(feature = "cli", arg(long))]
    pub out: PathBuf,
}

/// Where [`ReportJob::run`] wrote the curves.
#[derive(Debug, Clone, Serialize)]
pub struct ReportWritten {
    /// The output directory.
    pub out: PathBuf,
}

impl fmt::Display for ReportWritten {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "wrote the report to {}", self.out.display())
    }
}

impl BuildJob {
    /// Loads the corpus, builds the PCA (and the chart when the corpus is large enough for
    /// one) and writes the model.
    pub fn run(&self) -> Result<BuildReport> {
        let mapping = crate::Mapping::parse(&self.mapping)?;
        let corpus = Corpus::load(&self.corpus)?;
        let k = self
            .components
            .unwrap_or(DEFAULT_COMPONENTS)
            .min(corpus.len().saturating_sub(1).max(1));
        // Charting needs a neighbourhood for every point: skip it for tiny corpora.
        let chart =
            (self.chart_dim > 0 && corpus.len() > self.chart_dim + 2).then_some(self.chart_dim);
        let model = build_mapped_model(&corpus, mapping, k, chart, Some(45.min(k)))?;
        brdf::create_parent_dir(&self.out)?;
        model.save(&self.out)?;
        Ok(BuildReport {
            out: self.out.clone(),
            materials: corpus.len(),
            components: k,
            chart_dim: chart,
        })
    }
}

impl ReconstructJob {
    /// Projects the material, writes the reconstruction and reports its errors.
    pub fn run(&self) -> Result<ReconstructReport> {
        let model = Model::load(&self.model)?;
        brdf::create_parent_dir(&self.out)?;
        let encoder = crate::Encoder::parse(&self.encoder)?;
        let err = model.reconstruct_spec_to_file(&self.spec, self.k, encoder, &self.out)?;
        Ok(ReconstructReport {
            out: self.out.clone(),
            k: err.k,
            relative: err.relative,
            rms_log: err.rms_log,
        })
    }
}

impl ReportJob {
    /// Writes the model's curves.
    pub fn run(&self) -> Result<ReportWritten> {
        let model = Model::load(&self.model)?;
        crate::report::write_report(&model, &self.out)?;
        Ok(ReportWritten {
            out: self.out.clone(),
        })
    }
}

/// Measure how well models describe materials they were not built from: the job behind
/// `gantry model evaluate` (see [`leave_one_out`](crate::leave_one_out) for the errors).
///
/// Every corpus material is left out of the model it is scored on; materials given as
/// `unseen` are scored on the model of the whole corpus. Each mapping is one candidate.
///
/// # Examples
///
/// ```
/// use reduce::EvaluateJob;
///
/// let job = EvaluateJob {
///     corpus: ["lambert:kd=0.2", "lambert:kd=0.4", "ggx:alpha=0.3", "ggx:alpha=0.2"]
///         .map(String::from)
///         .to_vec(),
///     unseen: vec!["ggx:alpha=0.25".into()],
///     mapping: vec!["log".into(), "cosine-log".into()],
///     encoder: vec!["projection".into()],
///     k: vec![1, 2],
///     train_size: None,
///     out: None,
/// };
/// let report = job.run().unwrap();
/// assert_eq!(report.summaries.len(), 2 * 2 * 2); // mappings × sets × k (one encoder)
/// let s = &report.summaries[0];
/// assert_eq!((s.mapping.as_str(), s.set.as_str(), s.k), ("log", "leave-one-out", 1));
/// assert_eq!(s.encoder, "projection");
/// // the printed table names every candidate
/// let printed = report.to_string();
/// assert!(printed.lines().nth(1).unwrap().starts_with("log              projection leave-one-out"));
/// assert_eq!(s.materials, 4);
/// assert!(s.median_abs_log.is_finite() && s.cosine_rms > 0.0);
/// ```
#[derive(Debug, Clone)]
#[cfg_attr(feature = "cli", derive(clap::Args))]
pub struct EvaluateJob {
    /// Corpus: each material is reconstructed by the model of the others.
    #[cfg_attr(feature = "cli", arg(long, num_args = 1.., required = true))]
    pub corpus: Vec<String>,
    /// Materials outside the corpus, reconstructed by the model of the whole corpus.
    #[cfg_attr(feature = "cli", arg(long, num_args = 1..))]
    pub unseen: Vec<String>,
    /// Mappings to compare (`log`, `cosine-log`, `cosine-log:EPSILON`).
    #[cfg_attr(
        feature = "cli",
        arg(long, value_delimiter = ',', default_value = "log,cosine-log")
    )]
    pub mapping: Vec<String>,
    /// Encoders to compare (`projection`, `robust`).
    #[cfg_attr(
        feature = "cli",
        arg(long, value_delimiter = ',', default_value = "projection")
    )]
    pub encoder: Vec<String>,
    /// Numbers of components.
    #[cfg_attr(
        feature = "cli",
        arg(long, value_delimiter = ',', default_value = "10,45")
    )]
    pub k: Vec<usize>,
    /// Build each leave-one-out model from this many of the other materials (a seeded random
    /// subset per held-out material) instead of all of them: how the error falls as the
    /// corpus grows.
    #[cfg_attr(feature = "cli", arg(long))]
    pub train_size: Option<usize>,
    /// Folder for `scores.csv` (one row per material, mapping and k) and `summary.json`.
    #[cfg_attr(feature = "cli", arg(long))]
    pub out: Option<PathBuf>,
}

/// Means of the errors of one candidate on one set at one `k`.
#[derive(Debug, Clone, Serialize)]
pub struct EvaluateSummary {
    /// The mapping.
    pub mapping: String,
    /// The encoder.
    pub encoder: String,
    /// `leave-one-out` or `unseen`.
    pub set: String,
    /// Components asked for.
    pub k: usize,
    /// Materials scored.
    pub materials: usize,
    /// Mean relative log error.
    pub relative: f64,
    /// Mean RMS log error.
    pub rms_log: f64,
    /// Mean cosine-weighted relative RMS.
    pub cosine_rms: f64,
    /// Mean median |log|.
    pub median_abs_log: f64,
}

/// What [`EvaluateJob::run`] measured.
#[derive(Debug, Clone, Serialize)]
pub struct EvaluateReport {
    /// Means per mapping, set and `k`.
    pub summaries: Vec<EvaluateSummary>,
    /// Materials each leave-one-out model was built from, when fewer than all the others.
    pub train_size: Option<usize>,
    /// Every score: mapping, encoder, set, errors.
    pub scores: Vec<(String, String, String, crate::UnseenError)>,
    /// Where the files went.
    pub out: Option<PathBuf>,
}

impl fmt::Display for EvaluateReport {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        writeln!(
            f,
            "{:<16} {:<10} {:<14} {:>3} {:>4} {:>9} {:>8} {:>10} {:>11}",
            "mapping", "encoder", "set", "k", "n", "relative", "rms log", "cos rms", "median|log|"
        )?;
        for s in &self.summaries {
            writeln!(
                f,
                "{:<16} {:<10} {:<14} {:>3} {:>4} {:>9.4} {:>8.4} {:>10.4} {:>11.4}",
                s.mapping,
                s.encoder,
                s.set,
                s.k,
                s.materials,
                s.relative,
                s.rms_log,
                s.cosine_rms,
                s.median_abs_log
            )?;
        }
        if let Some(out) = &self.out {
            write!(f, "wrote scores.csv and summary.json to {}", out.display())?;
        }
        Ok(())
    }
}

impl EvaluateJob {
    /// Loads the corpus (and the unseen materials), scores every mapping and writes the files.
    pub fn run(&self) -> Result<EvaluateReport> {
        let mappings = self
            .mapping
            .iter()
            .map(|m| crate::Mapping::parse(m))
            .collect::<Result<Vec<_>>>()?;
        let encoders = self
            .encoder
            .iter()
            .map(|e| crate::Encoder::parse(e))
            .collect::<Result<Vec<_>>>()?;
        if self.k.is_empty() || self.k.contains(&0) {
            return Err(crate::ReduceError::InvalidParameter(
                "give at least one number of components, each at least 1".into(),
            ));
        }
        let corpus = Corpus::load(&self.corpus)?;
        let unseen = if self.unseen.is_empty() {
            None
        } else {
            Some(Corpus::load(&self.unseen)?)
        };
        let mut scores = Vec::new();
        let mut summaries = Vec::new();
        for m in &mappings {
            for enc in &encoders {
                let mut sets = vec![(
                    "leave-one-out",
                    crate::leave_one_out_sized(&corpus, m, *enc, &self.k, self.train_size)?,
                )];
                if let Some(u) = &unseen {
                    sets.push(("unseen", crate::score_unseen(&corpus, u, m, *enc, &self.k)?));
                }
                for (set, rows) in sets {
                    for (ki, &k) in self.k.iter().enumerate() {
                        let col: Vec<&crate::UnseenError> = rows.iter().map(|r| &r[ki]).collect();
                        let mean = |f: fn(&crate::UnseenError) -> f64| {
                            col.iter().map(|e| f(e)).sum::<f64>() / col.len().max(1) as f64
                        };
                        summaries.push(EvaluateSummary {
                            mapping: m.name(),
                            encoder: enc.name().into(),
                            set: set.into(),
                            k,
                            materials: col.len(),
                            relative: mean(|e| e.relative),
                            rms_log: mean(|e| e.rms_log),
                            cosine_rms: mean(|e| e.cosine_rms),
                            median_abs_log: mean(|e| e.median_abs_log),
                        });
                    }
                    for e in rows.into_iter().flatten() {
                        scores.push((m.name(), enc.name().to_string(), set.to_string(), e));
                    }
                }
            }
        }
        let report = EvaluateReport {
            train_size: self.train_size,
            summaries,
            scores,
            out: self.out.clone(),
        };
        if let Some(dir) = &self.out {
            std::fs::create_dir_all(dir).map_err(|e| crate::ReduceError::io(dir, e))?;
            let mut csv = String::from(
                "mapping,encoder,set,material,k,relative,rms_log,cosine_rms,median_abs_log\n",
            );
            for (m, enc, set, e) in &report.scores {
                csv += &format!(
                    "{m},{enc},{set},{},{},{},{},{},{}\n",
                    e.name, e.k, e.relative, e.rms_log, e.cosine_rms, e.median_abs_log
                );
            }
            let path = dir.join("scores.csv");
            brdf::write_atomic(&path, csv.as_bytes())?;
            let path = dir.join("summary.json");
            let json = serde_json::to_vec_pretty(&report.summaries).expect("plain data");
            brdf::write_atomic(&path, &json)?;
        }
        Ok(report)
    }
}
