//! The sparse-acquisition jobs behind `gantry sample model|plan|measure|reconstruct`.

use std::fmt;
use std::path::{Path, PathBuf};

use serde::Serialize;

use crate::error::{Result, SamplingError};
use crate::grid::SampleGrid;
use crate::methods::{self, Method, Model, PlanOptions};
use crate::plan::{measure_plan, Measurements, Plan};
use crate::training::TrainingSet;

/// Learn what a method needs (training tables, PCA basis, wavelet basis) from a corpus: the
/// job behind `gantry sample model`.
///
/// The four sampling jobs each take options (with the `cli` feature also the command's
/// arguments), `run` and return a [`SampleReport`]; they chain through files: model, plan,
/// measured values, reconstructed table.
///
/// # Examples
///
/// ```
/// use sampling::{Model, ModelJob};
///
/// let dir = std::env::temp_dir().join(format!("sampling-model-{}", std::process::id()));
/// std::fs::create_dir_all(&dir).unwrap();
/// // a linear-combination model of three analytic materials on a coarse sub-grid
/// let report = ModelJob {
///     method: "lincomb".parse().unwrap(),
///     corpus: vec!["lambert:kd=0.2".into(), "ggx:alpha=0.3".into(), "ggx:alpha=0.1".into()],
///     stride: vec![9, 9, 18],
///     noise: 0.0,
///     out: dir.join("model.bin"),
/// }
/// .run()
/// .unwrap();
/// let Model::LinComb(training) = sampling::load(&report.out).unwrap() else { panic!() };
/// assert_eq!(training.len(), 3);
/// # std::fs::remove_dir_all(&dir).unwrap();
/// ```
#[derive(Debug, Clone)]
#[cfg_attr(feature = "cli", derive(clap::Args))]
pub struct ModelJob {
    /// Method: lincomb, lincomb-whitened, lincomb-relative, pca, pullpush, wavelet.
    #[cfg_attr(feature = "cli", arg(long))]
    pub method: Method,
    /// Corpus: material specs, folders of neural-BRDF weights and/or .binary files, or corpus
    /// stores (see `gantry forms`).
    #[cfg_attr(feature = "cli", arg(long, num_args = 1.., required = true))]
    pub corpus: Vec<String>,
    /// Sub-grid strides over (θh, θd, φd) of the MERL grid.
    #[cfg_attr(feature = "cli", arg(long, num_args = 3, default_values_t = [1, 1, 1]))]
    pub stride: Vec<usize>,
    /// Expected relative measurement noise (regularises the PCA fit).
    #[cfg_attr(feature = "cli", arg(long, default_value_t = 0.01))]
    pub noise: f64,
    /// Output model file.
    #[cfg_attr(feature = "cli", arg(long))]
    pub out: PathBuf,
}

/// Choose the points to measure: CSV with header theta_h,theta_d,phi_d,channel (the job
/// behind `gantry sample plan`).
///
/// # Examples
///
/// ```
/// use sampling::{ModelJob, Plan, PlanJob};
///
/// # let dir = std::env::temp_dir().join(format!("sampling-{}-{}", "plan", std::process::id()));
/// # std::fs::create_dir_all(&dir).unwrap();
/// # ModelJob {
/// #     method: "lincomb".parse().unwrap(),
/// #     corpus: vec!["lambert:kd=0.2".into(), "ggx:alpha=0.3".into(), "ggx:alpha=0.1".into()],
/// #     stride: vec![9, 9, 18],
/// #     noise: 0.0,
/// #     out: dir.join("model.bin"),
/// # }
/// # .run()
/// # .unwrap();
/// let report = PlanJob {
///     method: "lincomb".parse().unwrap(),
///     n: 30,
///     model: Some(dir.join("model.bin")),
///     seed: 1,
///     out: dir.join("plan.csv"),
/// }
/// .run()
/// .unwrap();
/// assert_eq!(report.values_to_measure, Some(30));
/// assert_eq!(Plan::read_csv(&report.out).unwrap().len(), 30);
/// # std::fs::remove_dir_all(&dir).unwrap();
/// ```
#[derive(Debug, Clone)]
#[cfg_attr(feature = "cli", derive(clap::Args))]
pub struct PlanJob {
    /// Method: lincomb, lincomb-whitened, lincomb-relative, pca, pullpush, wavelet.
    #[cfg_attr(feature = "cli", arg(long))]
    pub method: Method,
    /// Number of values to measure. Wavelet, and pull-push with a wavelet model: 0 = one point per
    /// basis function, otherwise about n/3 points chosen coarse to fine, 3 channels per point.
    #[cfg_attr(feature = "cli", arg(long))]
    pub n: usize,
    /// Model file from `gantry sample model` (optional for pull-push: a uniform random plan on
    /// the full grid).
    #[cfg_attr(feature = "cli", arg(long))]
    pub model: Option<PathBuf>,
    /// Seed of the random choices.
    #[cfg_attr(feature = "cli", arg(long, default_value_t = 1))]
    pub seed: u64,
    /// Output plan CSV.
    #[cfg_attr(feature = "cli", arg(long))]
    pub out: PathBuf,
}

/// "Measure" a plan on a material (planar-sample gonioreflectometer model with noise): the job
/// behind `gantry sample measure`.
///
/// # Examples
///
/// ```
/// use sampling::{MeasureJob, Measurements, ModelJob, PlanJob};
///
/// # let dir = std::env::temp_dir().join(format!("sampling-{}-{}", "measure", std::process::id()));
/// # std::fs::create_dir_all(&dir).unwrap();
/// # ModelJob {
/// #     method: "lincomb".parse().unwrap(),
/// #     corpus: vec!["lambert:kd=0.2".into(), "ggx:alpha=0.3".into(), "ggx:alpha=0.1".into()],
/// #     stride: vec![9, 9, 18],
/// #     noise: 0.0,
/// #     out: dir.join("model.bin"),
/// # }
/// # .run()
/// # .unwrap();
/// # PlanJob {
/// #     method: "lincomb".parse().unwrap(),
/// #     n: 30,
/// #     model: Some(dir.join("model.bin")),
/// #     seed: 1,
/// #     out: dir.join("plan.csv"),
/// # }
/// # .run()
/// # .unwrap();
/// let report = MeasureJob {
///     spec: "ggx:alpha=0.2".into(),
///     plan: dir.join("plan.csv"),
///     seed: 1,
///     noise: 0.0,
///     out: dir.join("values.csv"),
/// }
/// .run()
/// .unwrap();
/// let measured = Measurements::read_csv(&report.out).unwrap();
/// assert_eq!(measured.values.len(), 30);
/// assert!(measured.values.iter().all(|v| *v >= 0.0));
/// # std::fs::remove_dir_all(&dir).unwrap();
/// ```
#[derive(Debug, Clone)]
#[cfg_attr(feature = "cli", derive(clap::Args))]
pub struct MeasureJob {
    /// Material spec to measure.
    pub spec: String,
    /// Plan CSV.
    #[cfg_attr(feature = "cli", arg(long))]
    pub plan: PathBuf,
    /// Seed of the noise.
    #[cfg_attr(feature = "cli", arg(long, default_value_t = 1))]
    pub seed: u64,
    /// Relative (log-normal) measurement noise.
    #[cfg_attr(feature = "cli", arg(long, default_value_t = 0.0))]
    pub noise: f64,
    /// Output values CSV.
    #[cfg_attr(feature = "cli", arg(long))]
    pub out: PathBuf,
}

/// Reconstruct a full table from the measured values of a plan: the job behind
/// `gantry sample reconstruct`.
///
/// # Examples
///
/// ```
/// use sampling::{MeasureJob, ModelJob, PlanJob, ReconstructJob};
///
/// # let dir = std::env::temp_dir().join(format!("sampling-{}-{}", "reconstruct", std::process::id()));
/// # std::fs::create_dir_all(&dir).unwrap();
/// # ModelJob {
/// #     method: "lincomb".parse().unwrap(),
/// #     corpus: vec!["lambert:kd=0.2".into(), "ggx:alpha=0.3".into(), "ggx:alpha=0.1".into()],
/// #     stride: vec![9, 9, 18],
/// #     noise: 0.0,
/// #     out: dir.join("model.bin"),
/// # }
/// # .run()
/// # .unwrap();
/// # PlanJob {
/// #     method: "lincomb".parse().unwrap(),
/// #     n: 30,
/// #     model: Some(dir.join("model.bin")),
/// #     seed: 1,
/// #     out: dir.join("plan.csv"),
/// # }
/// # .run()
/// # .unwrap();
/// # MeasureJob {
/// #     spec: "ggx:alpha=0.2".into(),
/// #     plan: dir.join("plan.csv"),
/// #     seed: 1,
/// #     noise: 0.0,
/// #     out: dir.join("values.csv"),
/// # }
/// # .run()
/// # .unwrap();
/// let report = ReconstructJob {
///     method: None,
///     plan: dir.join("plan.csv"),
///     values: dir.join("values.csv"),
///     model: Some(dir.join("model.bin")),
///     out: dir.join("ggx.binary"),
/// }
/// .run()
/// .unwrap();
/// let table = brdf::merl::read(&report.out).unwrap();
/// assert!(table.peak()[0] > 0.0);
/// # std::fs::remove_dir_all(&dir).unwrap();
/// ```
#[derive(Debug, Clone)]
#[cfg_attr(feature = "cli", derive(clap::Args))]
pub struct ReconstructJob {
    /// Method used for the plan (default: the one the model file was built for; pull-push
    /// without a model). A linear-combination model defaults to `lincomb`; a plan made with
    /// `lincomb-relative` should be reconstructed with it too, as it fits relative equations.
    #[cfg_attr(feature = "cli", arg(long))]
    pub method: Option<Method>,
    /// Plan CSV (checked against the values).
    #[cfg_attr(feature = "cli", arg(long))]
    pub plan: PathBuf,
    /// Values CSV: the plan's columns plus `value` (BRDF, 1/sr).
    #[cfg_attr(feature = "cli", arg(long))]
    pub values: PathBuf,
    /// Model file (optional for pull-push).
    #[cfg_attr(feature = "cli", arg(long))]
    pub model: Option<PathBuf>,
    /// Output MERL .binary file.
    #[cfg_attr(feature = "cli", arg(long))]
    pub out: PathBuf,
}

/// What a sampling job wrote.
#[derive(Debug, Clone, Serialize)]
pub struct SampleReport {
    /// The file written.
    pub out: PathBuf,
    /// For a plan, the number of values it asks to measure.
    pub values_to_measure: Option<usize>,
}

impl fmt::Display for SampleReport {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "wrote {}", self.out.display())?;
        if let Some(n) = self.values_to_measure {
            write!(f, " ({n} values to measure)")?;
        }
        Ok(())
    }
}

impl SampleReport {
    fn wrote(out: &Path) -> Self {
        SampleReport {
            out: out.to_path_buf(),
            values_to_measure: None,
        }
    }
}

/// The model of `path`, or for pull-push without one the full MERL grid.
fn model_or_grid(path: Option<&Path>, method: Method) -> Result<Model> {
    match path {
        Some(p) => crate::model_file::load(p),
        None if method == Method::PullPush => Ok(Model::Grid(SampleGrid::FULL)),
        None => Err(SamplingError::InvalidParameter(format!(
            "a model file is required for the method {method:?}"
        ))),
    }
}

impl ModelJob {
    /// Tabulates the corpus on the sub-grid, builds the method's model and writes it.
    pub fn run(&self) -> Result<SampleReport> {
        let [s0, s1, s2] = self.stride[..] else {
            return Err(SamplingError::InvalidParameter(format!(
                "the stride takes three values, not {}",
                self.stride.len()
            )));
        };
        let grid = SampleGrid::new(s0, s1, s2)?;
        let training = TrainingSet::from_inputs(&self.corpus, grid)?;
        let model = methods::build_model(self.method, training, self.noise)?;
        crate::model_file::save(&model, &self.out)?;
        Ok(SampleReport::wrote(&self.out))
    }
}

impl PlanJob {
    /// Chooses the points to measure and writes the plan.
    pub fn run(&self) -> Result<SampleReport> {
        let model = model_or_grid(self.model.as_deref(), self.method)?;
        let options = PlanOptions {
            seed: self.seed,
            ..Default::default()
        };
        let plan = methods::plan(self.method, self.n, &model, options)?;
        plan.write_csv(&self.out)?;
        Ok(SampleReport {
            out: self.out.clone(),
            values_to_measure: Some(plan.points.len()),
        })
    }
}

impl MeasureJob {
    /// Evaluates the material at the plan's points, with noise, and writes the values.
    pub fn run(&self) -> Result<SampleReport> {
        let plan = Plan::read_csv(&self.plan)?;
        let material = brdf::load(&self.spec)?;
        let values = measure_plan(&plan, &material, self.noise, self.seed)?;
        values.write_csv(&self.out)?;
        Ok(SampleReport::wrote(&self.out))
    }
}

impl ReconstructJob {
    /// The method: the one asked for, else the one the model was built for.
    fn method(&self, model: Option<&Model>) -> Method {
        match (self.method, model) {
            (Some(m), _) => m,
            (None, None | Some(Model::Grid(_))) => Method::PullPush,
            (None, Some(Model::LinComb(_))) => Method::LinComb(Default::default()),
            (None, Some(Model::LogPca(_))) => Method::Pca,
            (None, Some(Model::Wavelet(_))) => Method::Wavelet,
        }
    }

    /// Reconstructs the full table from the measured values and writes it.
    pub fn run(&self) -> Result<SampleReport> {
        let plan = Plan::read_csv(&self.plan)?;
        let values = Measurements::read_csv(&self.values)?;
        if values.points != plan.points {
            return Err(SamplingError::InvalidParameter(format!(
                "{}: the measured points are not those of the plan {}",
                self.values.display(),
                self.plan.display()
            )));
        }
        let loaded = self
            .model
            .as_deref()
            .map(crate::model_file::load)
            .transpose()?;
        let method = self.method(loaded.as_ref());
        let model = match loaded {
            Some(model) => model,
            None => model_or_grid(None, method)?,
        };
        let table = methods::reconstruct(method, &values, &model)?.to_merl()?;
        brdf::merl::write(&self.out, &table)?;
        Ok(SampleReport::wrote(&self.out))
    }
}
