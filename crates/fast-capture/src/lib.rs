//! # fast-capture — a short gantry capture planned and completed by the model
//!
//! Thesis chapter 6 exists to shorten acquisition: a material of the space the corpus spans is
//! determined by far fewer measurements than a dense table. This crate applies it to the
//! gantry of chapter 3. A full capture visits 330 lamp positions with 18 exposures each (4.1 h
//! of rig clock); a fast one visits a few positions chosen for the log-PCA model, takes only
//! the shorter exposures, and completes the table from the model:
//!
//! 1. [`Coverage`]: which table entries (channel, bin) each candidate lamp position reaches on
//!    this rig, computed by the capture's own sample code.
//! 2. [`plan()`]: a greedy Bayesian A-optimal choice of positions for the model's components
//!    within a clock budget ([`PlanOptions`], [`ClockModel`]), stored as [`CapturePlan`].
//! 3. [`run()`]: the capture of the planned positions (an `acquire` job, resumable), then
//!    [`complete()`]: measured entries kept, the others predicted by the model with their
//!    uncertainty; the files of [`FastDir`] and the [`FastReport`].
//!
//! A plan on the simulated rig at a small sensor scale, with a small model:
//!
//! ```
//! use acquire::{JobSpec, SimSetup, Station};
//! use fast_capture::{plan_capture, FastOptions, PlanOptions};
//!
//! let mut corpus = reduce::Corpus::new(reduce::MATERIAL_DIM);
//! for (i, alpha) in [0.1, 0.3, 0.5, 0.2].into_iter().enumerate() {
//!     let ggx = brdf::analytic::Ggx { kd: [0.2, 0.3, 0.1], ks: [0.9; 3], alpha, ior: 1.5 };
//!     corpus.push_values(format!("m{i}"), &brdf::MerlTable::tabulate(&ggx).values())?;
//! }
//! let model = reduce::build_model(&corpus, 3, None, None)?;
//! let spec = JobSpec::new("lambert:kd=0.5", 1);
//! let station = Station::simulated(&spec, &SimSetup::with_scale(0.05))?;
//! let options = FastOptions {
//!     plan: PlanOptions { max_positions: 4, candidates: 24, components: 3, ..PlanOptions::default() },
//!     ..FastOptions::default()
//! };
//! let plan = plan_capture(&station, &spec, &model, &options)?;
//! assert_eq!(plan.angles_deg.len(), 4);
//! assert!(plan.predicted_clock_s <= options.plan.budget_s);
//! assert!(plan.steps.windows(2).all(|w| w[1].predicted_log_sd <= w[0].predicted_log_sd));
//! # Ok::<(), Box<dyn std::error::Error>>(())
//! ```

#![warn(missing_docs)]

mod complete;
mod coverage;
mod error;
mod job;
mod plan;

pub use complete::{complete, Completion, Residual};
pub use coverage::Coverage;
pub use error::{FastError, Result};
pub use job::{
    plan_capture, run, scores, FastDir, FastOptions, FastOutcome, FastReport, Scores, TruthScores,
};
pub use plan::{
    even_angles, plan, residual_log_var, CapturePlan, ClockModel, PlanOptions, PlanStep, Weighting,
    DEFAULT_MAX_EXPOSURE_S, PLAN_VERSION,
};
