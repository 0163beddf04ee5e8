//! # fit — analytic reflectance models fitted to measured BRDFs (thesis §3.7)
//!
//! A measured table goes in, a fitted analytic model comes out as a material spec:
//!
//! 1. **Prepare the data.** [`FitData`] holds the valid bins of a measured table (NaN and
//!    missing bins excluded and counted); the bin geometry is computed once per process
//!    ([`grid_geometry`]). [`Subset`] fits a seeded subset of the bins instead of all.
//! 2. **Choose a model.** [`ModelKind`] lists the fittable models (every isotropic analytic
//!    model of `brdf::analytic`, plus two-lobe Lafortune, Cook-Torrance and GGX) with per-channel
//!    albedos and shared shape parameters, bounds by reparameterisation, and the
//!    `brdf::analytic` model of a parameter vector ([`ModelKind::model`]): the fitter evaluates
//!    `brdf`'s own models, on [`Dual`] numbers for the gradients.
//! 3. **Choose an objective.** [`Objective`] is the thesis's log-space error, Ngan et al.'s
//!    cosine-weighted L2 (θ ≤ 80°), or the sampling crate's rendered-sphere error.
//! 4. **Fit.** [`fit()`] runs Levenberg-Marquardt on normal equations accumulated in parallel
//!    over the bins, with exact gradients by forward-mode differentiation and a deterministic
//!    multi-start ([`FitOptions`]); the [`FitResult`] names its material spec
//!    ([`FitResult::spec`]).
//! 5. **Compare.** [`study_corpus`] fits every model with every objective across a corpus and
//!    writes the comparison as CSV ([`write_csv`], [`markdown_summary`]).
//!
//! [`FitJob`] is the job behind `gantry fit`: options in, one run, a serde report out.
//!
//! # Examples
//!
//! ```
//! use fit::{fit, FitData, FitOptions, ModelKind, Objective, Subset};
//! // A "measured" table: a GGX material tabulated on the MERL grid.
//! let truth = brdf::load("ggx:kd=0.2/0.1/0.05,ks=0.6,alpha=0.2,ior=1.6").unwrap();
//! let data = FitData::new(&truth.tabulate()).unwrap();
//! let opts = FitOptions {
//!     objective: Objective::Log,
//!     subset: Subset::Random { bins: 2000, seed: 1 },
//!     starts: 1,
//!     ..FitOptions::default()
//! };
//! let result = fit(ModelKind::Ward, &data, &opts).unwrap();
//! // Every fit names a material every command accepts.
//! assert!(brdf::load(&result.spec()).is_ok());
//! assert!(result.fit_error < 0.2);
//! ```

#![warn(missing_docs)]
#![allow(clippy::needless_range_loop)]

mod data;
mod dual;
mod error;
mod job;
mod model;
mod objective;
mod solve;
mod study;

pub use data::{grid_geometry, Exclusions, FitData, Subset, NGAN_MAX_THETA_DEG};
pub use error::{FitError, Result};
pub use job::{FitJob, FitReport, SingleFit, StudyReport};
pub use model::{ModelKind, Parametric};
pub use objective::{jacobian, log_readings, residuals, Errors, EvalRows, LogReadings, Objective};
pub use solve::{fit, fit_rows, FitOptions, FitResult};

#[cfg(test)]
mod tests;

pub use data::{GridGeometry, Rows};
pub use dual::{Dual, Real};
pub use model::{Bound, Geom, Model, ParamDef};
pub use objective::Normal;
pub use solve::StartOutcome;
pub use study::{
    markdown_summary, study_corpus, study_material, write_csv, Ranking, StudyOptions, StudyRow,
};
