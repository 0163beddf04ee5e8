//! The model jobs behind `gantry model build|reconstruct|report`.

use std::fmt;
use std::path::PathBuf;

use serde::Serialize;

use crate::corpus::Corpus;
use crate::error::Result;
use crate::model::{build_model, Model, DEFAULT_COMPONENTS};

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
/// }
/// .run()
/// .unwrap();
/// // a corpus member lies on the line through the mean along the one component
/// let report = ReconstructJob {
///     spec: "ggx:alpha=0.3".into(),
///     model,
///     k: 1,
///     out: dir.join("ggx.binary"),
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
        let corpus = Corpus::load(&self.corpus)?;
        let k = self
            .components
            .unwrap_or(DEFAULT_COMPONENTS)
            .min(corpus.len().saturating_sub(1).max(1));
        // Charting needs a neighbourhood for every point: skip it for tiny corpora.
        let chart =
            (self.chart_dim > 0 && corpus.len() > self.chart_dim + 2).then_some(self.chart_dim);
        let model = build_model(&corpus, k, chart, Some(45.min(k)))?;
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
        let err = model.reconstruct_spec_to_file(&self.spec, self.k, &self.out)?;
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
