//! # sampling — sparse BRDF acquisition (thesis chapter 6, and beyond)
//!
//! ```
//! use brdf::analytic::{BlinnPhong, Lambert};
//! use brdf::Brdf;
//! use sampling::methods::{self, Method, Model, PlanOptions};
//! use sampling::{measure_plan, metrics, training::TrainingSet, GridTable, SampleGrid};
//!
//! // a training corpus on a coarse sub-grid of the MERL grid (reduced sizes for the example)
//! let grid = SampleGrid::new(6, 6, 12).unwrap();
//! let training: Vec<Box<dyn Brdf>> = (0..6)
//!     .map(|i| -> Box<dyn Brdf> {
//!         let kd = [0.1 + 0.1 * i as f64, 0.3, 0.5 - 0.05 * i as f64];
//!         if i < 3 {
//!             Box::new(Lambert { kd })
//!         } else {
//!             Box::new(BlinnPhong { kd, ks: [0.3; 3], exponent: 10.0 * i as f64 })
//!         }
//!     })
//!     .collect();
//! let set = TrainingSet::from_brdfs(&training, grid).unwrap();
//! let model = Model::LinComb(set);
//! let method: Method = "lincomb".parse().unwrap();
//! // plan 40 measurements, measure a material of the training span, reconstruct
//! let plan = methods::plan(method, 40, &model, PlanOptions::default()).unwrap();
//! let target = BlinnPhong { kd: [0.4, 0.3, 0.2], ks: [0.3; 3], exponent: 40.0 };
//! let measured = measure_plan(&plan, &target, 0.0, 7).unwrap();
//! let table = methods::reconstruct(method, &measured, &model).unwrap();
//! let err = metrics::log_rms_relative(&GridTable::tabulate(&target, grid), &table).unwrap();
//! assert!(err < 0.05, "relative log RMS error {err}");
//! ```
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
//! * [`ModelJob`], [`PlanJob`], [`MeasureJob`], [`ReconstructJob`]: the jobs behind
//!   `gantry sample`, each options in, `run()`, a [`SampleReport`] out.

#![warn(missing_docs)]
#![allow(clippy::needless_range_loop)]

pub mod error;
pub mod grid;
mod job;
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
pub use job::{MeasureJob, ModelJob, PlanJob, ReconstructJob, SampleReport};
pub use methods::{plan, reconstruct, Method, Model, PlanOptions};
pub use plan::{measure_plan, Measurements, Plan, SamplePoint};
