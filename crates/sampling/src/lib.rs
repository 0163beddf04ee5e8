//! # sampling — sparse BRDF acquisition (thesis chapter 6, and beyond)
//!
//! Plan which (θh, θd, φd, channel) values to measure, measure them, and reconstruct a dense
//! table from them. The work flows as follows:
//!
//! 1. **Train.** A [`TrainingSet`] holds a corpus tabulated on a [`SampleGrid`], the full MERL
//!    grid or a regular sub-grid of it ([`GridTable`] is one table on such a grid).
//! 2. **Build the method's model.** [`build_model`] turns a training set into the [`Model`] a
//!    [`Method`] needs: the set itself for the linear combination of thesis §6.5
//!    ([`select_rows`], [`fit_coefficients`]), a [`LogPcaModel`] (log-space PCA with A-optimal
//!    rows and a Bayesian fit, beyond the thesis), a [`WaveletPatternModel`] (the Common Wavelet
//!    Basis pattern and sparse solve of thesis §6.3), or only a grid for [`pull_push`]
//!    (thesis §6.4). [`save`] and [`load`] keep it in a binary file.
//! 3. **Plan.** [`plan`] chooses the points of a [`Plan`] (CSV on disk).
//! 4. **Measure.** [`measure_plan`] simulates a planar-sample gonioreflectometer with noise and
//!    gives [`Measurements`].
//! 5. **Reconstruct.** [`reconstruct`] fills the grid from the measurements; [`metrics`] has the
//!    relative log-space RMS error and the relative RMS error of a rendered sphere.
//!
//! [`ModelJob`], [`PlanJob`], [`MeasureJob`] and [`ReconstructJob`] are the jobs behind
//! `gantry sample model|plan|measure|reconstruct`, each options in, `run()`, a
//! [`SampleReport`] out.
//!
//! # Examples
//!
//! ```
//! use brdf::analytic::{BlinnPhong, Lambert};
//! use brdf::Brdf;
//! use sampling::{self, Method, Model, PlanOptions};
//! use sampling::{measure_plan, metrics, TrainingSet, GridTable, SampleGrid};
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
//! let plan = sampling::plan(method, 40, &model, PlanOptions::default()).unwrap();
//! let target = BlinnPhong { kd: [0.4, 0.3, 0.2], ks: [0.3; 3], exponent: 40.0 };
//! let measured = measure_plan(&plan, &target, 0.0, 7).unwrap();
//! let table = sampling::reconstruct(method, &measured, &model).unwrap();
//! let err = metrics::log_rms_relative(&GridTable::tabulate(&target, grid), &table).unwrap();
//! assert!(err < 0.05, "relative log RMS error {err}");
//! ```

#![warn(missing_docs)]
#![allow(clippy::needless_range_loop)]

mod error;
mod grid;
mod job;
mod lincomb;
mod logpca;
mod methods;
pub mod metrics;
mod model_file;
mod plan;
mod pullpush;
mod training;
mod wavelet_pattern;

pub use lincomb::{
    combine, eigenvalue_ratio, fit_coefficients, fit_coefficients_weighted, row_matrix,
    select_rows, select_rows_weighted, RowWeights, SearchBasis, Selection, SwapSearch,
};
pub use logpca::LogPcaModel;
pub use methods::{
    build_model, plan_from_rows, uniform_plan, Equations, LinCombOptions, WAVELET_CGLS_ITERATIONS,
    WAVELET_DAMPING,
};
pub use model_file::{from_bytes, load, save, to_bytes};
pub use plan::write_atomic;
pub use pullpush::{pull_push, pull_push_channel, pull_push_channel_with_gain, Domain};
pub use training::{
    from_log_clamped, measurable, measurable_rows, row_of, tabulate_nbrdf_f32, to_log, TrainingSet,
    LOG_FLOOR,
};
pub use wavelet_pattern::{cgls, CoarseGrid, WaveletPatternModel};

pub use error::{Result, SamplingError};
pub use grid::{GridTable, SampleGrid};
pub use job::{MeasureJob, ModelJob, PlanJob, ReconstructJob, SampleReport};
pub use methods::{plan, reconstruct, Method, Model, PlanOptions};
pub use plan::{measure_plan, Measurements, Plan, SamplePoint};
