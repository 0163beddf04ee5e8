//! # reduce — linear and non-linear models of the space of measured BRDFs
//!
//! ```
//! use reduce::corpus::Corpus;
//! use reduce::model::build_model;
//!
//! // a corpus of log-space vectors (here 8 synthetic materials of 50 values; a MERL corpus is
//! // loaded with `Corpus::load(&["merl:chrome", "merl:pink-felt", ...])`)
//! let mut corpus = Corpus::new(50);
//! let material = |i: usize, d: usize| {
//!     let (w1, w2, w3) = (1.0 + i as f64, 1.0 + ((i * i) % 5) as f64, 0.5 + ((3 * i) % 4) as f64);
//!     w1 * (1.0 + d as f64) + w2 * (-(d as f64) / 5.0).exp() + w3 * (d % 7) as f64
//! };
//! for i in 0..8 {
//!     let values: Vec<f64> = (0..50).map(|d| material(i, d)).collect();
//!     corpus.push_values(format!("m{i}"), &values).unwrap();
//! }
//! // PCA in log space (thesis §4.1), at most N − 1 = 7 components
//! let model = build_model(&corpus, 7, None, None).unwrap();
//! let k = model.components();
//! assert!(k >= 2 && k <= 7);
//! let ev = &model.pca.eigenvalues;
//! assert!(ev.windows(2).all(|w| w[0] >= w[1]));
//! // a corpus member is recovered (within 1 %) from its coordinates on all components
//! let x: Vec<f64> = (0..k).map(|c| model.pca.coords[(2, c)]).collect();
//! let back = model.synthesize(&x).unwrap();
//! for d in [0, 17, 49] {
//!     let v = material(2, d);
//!     assert!((back[d] - v).abs() < 1e-2 * v, "{d}: {} vs {v}", back[d]);
//! }
//! ```
//!
//! Each measured BRDF (a 90 × 90 × 180 × RGB MERL table) is one vector; the corpus of
//! materials is analysed as in chapters 2.5 and 4 of Matusik's thesis:
//!
//! * [`corpus`]: loading materials (NBRDF directories, `.binary` files) as log-space vectors.
//! * [`gram`]: the streamed `N × N` Gram matrix.
//! * [`pca`]: PCA through the Gram matrix (eqs. 4.1–4.3), projection and reconstruction.
//! * [`ooc`]: out-of-core PCA of corpora streamed from a store (Gram and randomized SVD).
//! * [`nmf`]: non-negative matrix factorisation (Lee–Seung multiplicative updates for the
//!   divergence of eq. 2.38; Frobenius objective by multiplicative updates or HALS).
//! * [`mds`], [`isomap`], [`lle`]: classical MDS, Isomap and locally linear embedding.
//! * [`charting`]: Brand's manifold charting (eqs. 2.44–2.55).
//! * [`model`]: the versioned binary model file and the `build / reconstruct` operations.
//! * [`report`]: CSV tables of a model and, with feature `plot`, its PNG plots (`plot`).
//! * [`plausibility`]: plausibility of long moves in the linear space and in the chart.
//! * [`procrustes`]: Procrustes disparity between two embeddings.
//! * [`spec`]: `pca:<model.bin>?…` material specs (points of a model's space as materials).
//! * [`BuildJob`], [`ReconstructJob`], [`ReportJob`]: the jobs behind `gantry model`, each
//!   options in, `run()`, a serde report out.

#![warn(missing_docs)]

pub mod charting;
pub mod corpus;
pub mod error;
pub mod gram;
pub mod isomap;
mod job;
pub mod lle;
pub mod mds;
pub mod model;
pub mod nmf;
pub mod ooc;
mod ordered;
pub mod pca;
pub mod plausibility;
#[cfg(feature = "plot")]
pub mod plot;
pub mod procrustes;
pub mod report;
pub mod spec;

pub use error::{ReduceError, Result};
pub use job::{BuildJob, BuildReport, ReconstructJob, ReconstructReport, ReportJob, ReportWritten};
