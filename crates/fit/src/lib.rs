//! # fit — analytic reflectance models fitted to measured BRDFs (thesis §3.7)
//!
//! * [`ModelKind`]: the fittable models (every isotropic analytic model of `brdf::analytic`,
//!   plus two-lobe Lafortune, Cook-Torrance and GGX) with per-channel albedos and shared shape
//!   parameters, bounds by reparameterisation, the `brdf::analytic` model of a parameter vector
//!   ([`ModelKind::model`]: the fitter evaluates `brdf`'s own models, on [`dual::Dual`] numbers
//!   for the gradients), and the material spec of a fit.
//! * [`FitData`]: the valid bins of a measured table (NaN and missing bins excluded and
//!   counted); the bin geometry is computed once per process ([`data::grid_geometry`]).
//! * [`Objective`]: the thesis's log-space error, Ngan et al.'s cosine-weighted L2 (θ ≤ 80°),
//!   and the sampling crate's rendered-sphere error.
//! * [`fit()`]: Levenberg-Marquardt on the normal equations accumulated in parallel over all
//!   valid bins (or a seeded subset), exact gradients by forward-mode differentiation, and a
//!   deterministic multi-start.
//! * [`study`]: the corpus-wide comparison and its CSV.
//!
//! ```
//! use fit::{fit, FitData, FitOptions, ModelKind, Objective, Subset};
//! // A "measured" table: a GGX material tabulated on the MERL grid.
//! let truth = brdf::spec::load("ggx:kd=0.2/0.1/0.05,ks=0.6,alpha=0.2,ior=1.6").unwrap();
//! let data = FitData::new(&truth.tabulate()).unwrap();
//! let opts = FitOptions {
//!     objective: Objective::Log,
//!     subset: Subset::Random { bins: 2000, seed: 1 },
//!     starts: 1,
//!     ..FitOptions::default()
//! };
//! let result = fit(ModelKind::Ward, &data, &opts).unwrap();
//! // Every fit names a material every command accepts.
//! assert!(brdf::spec::load(&result.spec()).is_ok());
//! assert!(result.fit_error < 0.2);
//! ```

#![warn(missing_docs)]
#![allow(clippy::needless_range_loop)]

pub mod data;
pub mod dual;
pub mod error;
mod job;
pub mod model;
pub mod objective;
pub mod solve;
pub mod study;

pub use data::{Exclusions, FitData, Subset};
pub use error::{FitError, Result};
pub use job::{FitJob, FitReport, SingleFit, StudyReport};
pub use model::{ModelKind, Parametric};
pub use objective::{log_readings, Errors, EvalRows, LogReadings, Objective};
pub use solve::{fit, fit_rows, FitOptions, FitResult};

#[cfg(test)]
mod tests;
