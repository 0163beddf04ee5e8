//! # sampling — sparse BRDF acquisition (thesis chapter 6, and beyond)
//!
//! Plan which (θh, θd, φd, channel) values to measure, and reconstruct a dense table from them.
//!
//! * [`lincomb`]: linear combination of training BRDFs, greedy swap selection of rows
//!   minimising the eigenvalue ratio of `XᵀX`, pseudo-inverse coefficients (§6.5).
//! * [`logpca`]: log-space PCA basis with A-optimal sample rows and a Bayesian (ridge) fit.
//! * [`wavelet_pattern`]: Common-Wavelet-Basis sample points and the sparse solve of `H c = g`
//!   (§6.3).
//! * [`pullpush`]: pull-push scattered-data reconstruction with the tent filters of §6.4.
//! * [`mod@plan`]: plan / values CSV formats and a simulated noisy measurement of a plan.
//! * [`metrics`]: relative log-space RMS error and relative RMS error of a rendered sphere.
//! * [`methods`]: [`methods::plan`] and [`methods::reconstruct`], one call per CLI verb.
//! * [`model_file`]: the binary model file (`--model model.bin`).
//! * [`grid`]: the MERL grid and regular sub-grids of it, on which models are trained.

#![warn(missing_docs)]
#![allow(clippy::needless_range_loop)]

pub mod error;
pub mod grid;
pub mod lincomb;
pub mod logpca;
pub mod methods;
pub mod metrics;
pub mod model_file;
pub mod plan;
pub mod pullpush;
pub mod training;
pub mod wavelet_pattern;

pub use error::{Result, SamplingError};
pub use grid::{GridTable, SampleGrid};
pub use methods::{plan, reconstruct, Method, Model, PlanOptions};
pub use plan::{measure_plan, Measurements, Plan, SamplePoint};
