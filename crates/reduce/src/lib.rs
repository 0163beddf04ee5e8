//! # reduce — linear and non-linear models of the space of measured BRDFs
//!
//! Each measured BRDF (a 90 × 90 × 180 × RGB MERL table) is one vector of
//! `D = 3 × 1,458,000` values, channel-major, every bin kept, each value `f` (1/sr) stored as
//! `ln(max(f, 0) + LOG_FLOOR)`. This crate analyses a corpus of such vectors as chapters 2.5
//! and 4 of the thesis do. The work flows as follows:
//!
//! 1. **Load a corpus.** [`Corpus`] (the `brdf` corpus, re-exported with the `f32` helpers
//!    [`to_log`] and [`from_log`]) holds the log-space vectors of neural-BRDF directories,
//!    `.binary` files, specs or stores (thesis §4.1; see [`brdf::LogTransform`] for why the
//!    floor is added).
//! 2. **Find the linear model.** [`gram_matrix`] streams the `N × N` Gram matrix, and [`Pca`]
//!    decomposes it into eigenvalues, basis and coordinates (thesis eqs. 4.1–4.3);
//!    [`fit_out_of_core`] does the same for corpora streamed from a store, by Gram matrix or
//!    randomized SVD.
//! 3. **Build the model.** [`build_model`] fits the PCA ([`DEFAULT_COMPONENTS`] components by
//!    default in [`BuildJob`]) and, optionally, a manifold chart ([`DEFAULT_CHART_DIM`]
//!    dimensions by default);
//!    [`Model`] is the result, saved as the versioned binary `model.bin` (thesis §4.1, §4.4),
//!    with projection, reconstruction and synthesis of materials.
//! 4. **Chart the manifold.** [`Charts`] fits Brand's manifold charting (thesis §2.5.2, §4.4,
//!    eqs. 2.44–2.55) and [`Charts::connect`] joins it into a [`Chart`] of a chosen dimension.
//!    [`long_move_comparison`] scores long moves in the chart against the same moves in the
//!    linear space by their [`Plausibility`] (thesis §4.3–4.4, Fig. 4-7).
//! 5. **Compare other reductions.** [`nmf`] is non-negative matrix factorisation (Lee–Seung
//!    multiplicative updates for the divergence of eq. 2.38, or the Frobenius objective by
//!    multiplicative updates or HALS; thesis §4.2.1); [`classical_mds`], [`isomap`] and [`lle`]
//!    are the embeddings of thesis §2.5; [`disparity`] compares two embeddings up to a
//!    similarity transform (Procrustes).
//! 6. **Use the model's space.** [`PcaSpec`] is the `pca:<model.bin>?…` material spec, a point
//!    of a model's space as a material (thesis §4.2), available to every spec-taking function
//!    after [`register_spec_resolver`].
//! 7. **Report.** [`write_report`] writes the CSV tables of a model and, with feature `plot`, its
//!    PNG plots ([`Report`]).
//!
//! [`BuildJob`], [`ReconstructJob`] and [`ReportJob`] are the jobs behind
//! `gantry model build|reconstruct|report`: options in, `run()`, a serde report out.
//! [`build_model`] has a longer worked example from corpus to synthesis.
//!
//! # Examples
//!
//! ```
//! use reduce::{build_model, Corpus};
//!
//! // five synthetic "materials" of 40 values each, two factors apart (a MERL corpus holds
//! // 4.4 M values per material: `Corpus::load(&["merl:chrome", ...])`)
//! let value = |i: usize, d: usize| 0.05 + 0.2 * (1 + i % 3) as f64 * (-(d as f64) / 8.0).exp()
//!     + 0.01 * (i / 2) as f64 * d as f64;
//! let mut corpus = Corpus::new(40);
//! for i in 0..5 {
//!     let values: Vec<f64> = (0..40).map(|d| value(i, d)).collect();
//!     corpus.push_values(format!("m{i}"), &values).unwrap();
//! }
//! let model = build_model(&corpus, 4, None, None).unwrap();
//! // the eigenvalues fall, and a material comes back from its coordinates (log-space PCA)
//! assert!(model.pca.eigenvalues.windows(2).all(|w| w[0] >= w[1]));
//! let k = model.components();
//! let x: Vec<f64> = (0..k).map(|c| model.pca.coords[(3, c)]).collect();
//! let back = model.synthesize(&x).unwrap();
//! assert!((0..40).all(|d| (back[d] - value(3, d)).abs() < 1e-2 * value(3, d)));
//! ```

#![warn(missing_docs)]

mod charting;
mod corpus;
mod decode;
mod encode;
mod error;
mod gram;
mod heldout;
mod isomap;
mod job;
mod lle;
mod mapping;
mod mds;
mod model;
mod nmf;
mod ooc;
mod ordered;
mod pca;
mod plausibility;
#[cfg(feature = "plot")]
mod plot;
mod procrustes;
mod report;
mod spec;

pub use charting::{held_out_errors, Chart, ChartingConfig, Charts, HeldOut, RoundTrip};
pub use corpus::{from_log, log_vector, to_log, Corpus, Source, LOG_FLOOR, MATERIAL_DIM};
pub use decode::Decoder;
pub use encode::{least_absolute, robust_sample, Encoder, ROBUST_SAMPLE, ROBUST_SEED};
pub use gram::{
    column_means, cross_gram_matrix, dot, gram_matrix, gram_matrix_with, GramKernel, BLOCKED_ROWS,
};
pub use heldout::{
    leave_one_out, leave_one_out_sized, score_unseen, UnseenError, TRAINING_SUBSET_SEED,
};
pub use isomap::{
    connected_components, geodesic_distances, isomap, neighbourhood_graph, ComponentEmbedding,
    DisconnectedPolicy, Isomap, Neighbourhood,
};
pub use lle::{lle, DEFAULT_REGULARISATION};
pub use mapping::{Mapping, MIN_COSINE_PRODUCT};
pub use mds::{classical_mds, euclidean_distances, Embedding};
pub use model::{
    build_mapped_model, build_model, chart_errors, chart_pca_coords, ChartErrors, Model,
    ReconstructionError, DEFAULT_CHART_DIM, DEFAULT_COMPONENTS,
};
pub use nmf::{kl_divergence, nmf, nmf_from, random_init, Nmf, NmfConfig, Solver};
pub use ooc::{
    fit as fit_out_of_core, principal_cosines, ColumnPanels, InMemory, OocOptions, OocStats,
    PcaMethod, SourceError,
};
pub use pca::{residual_curve, Pca};
pub use plausibility::{
    highlight_hole_fraction, long_move_comparison, median_by_step, move_pairs, MoveRow,
    Plausibility, Reference, HIGHLIGHT_BINS, RANGE_MARGIN,
};
#[cfg(feature = "plot")]
pub use plot::Series;
pub use procrustes::disparity;
pub use report::{write_report, Report};
pub use spec::{register_spec_resolver, PcaPoint, PcaSpec, PcaSpecs};

pub use error::{ReduceError, Result};
pub use job::{
    BuildJob, BuildReport, EvaluateJob, EvaluateReport, EvaluateSummary, ReconstructJob,
    ReconstructReport, ReportJob, ReportWritten,
};
