//! # reduce — linear and non-linear models of the space of measured BRDFs
//!
//! ```
//! use reduce::corpus::Corpus;
//! use reduce::model::build_model;
//!
//! // a corpus of log-space vectors (here 8 synthetic materials of 50 values; a MERL corpus is
//! // loaded with `Corpus::load(&["merl:chrome", "merl:pink-felt", ...])`)
//! let mut corpus = Corpus::new(50);
//! for i in 0..8 {
//!     let a = 0.1 + 0.1 * i as f64;
//!     let values: Vec<f64> = (0..50).map(|d| a * (1.0 + d as f64) + (1.0 - a) * 0.2).collect();
//!     corpus.push_values(format!("m{i}"), &values).unwrap();
//! }
//! // PCA in log space (thesis §4.1): three components, coordinates of every material
//! let model = build_model(&corpus, 3, None, None).unwrap();
//! assert_eq!(model.components(), 3);
//! let ev = &model.pca.eigenvalues;
//! assert!(ev.windows(2).all(|w| w[0] >= w[1]));
//! // reconstructing a corpus member from its coordinates on all components recovers it
//! let x: Vec<f64> = (0..3).map(|k| model.pca.coords[(2, k)]).collect();
//! let back = model.synthesize(&x).unwrap();
//! let first = 0.3 * 1.0 + 0.7 * 0.2;
//! assert!((back[0] - first).abs() < 1e-2 * first, "{} vs {first}", back[0]);
//! ```
//!
//! Each measured BRDF (a 90 × 90 × 180 × RGB MERL table) is one vector; the corpus of
//! materials is analysed as in chapters 2.5 and 4 of Matusik's thesis:
//!
//! * [`corpus`]: loading materials (NBRDF directories, `.binary` files) as log-space vectors.
//! * [`gram`]: the streamed `N × N` Gram matrix.
//! * [`pca`]: PCA through the Gram matrix (eqs. 4.1–4.3), projection and reconstruction.
//! * [`nmf`]: non-negative matrix factorisation (Lee–Seung multiplicative updates, eq. 2.38).
//! * [`mds`], [`isomap`], [`lle`]: classical MDS, Isomap and locally linear embedding.
//! * [`charting`]: Brand's manifold charting (eqs. 2.44–2.55).
//! * [`model`]: the versioned binary model file and the `build / reconstruct` operations.
//! * [`report`]: CSV tables of a model and, with feature `plot`, its PNG plots (`plot`).
//! * [`plausibility`]: plausibility of long moves in the linear space and in the chart.
//! * [`procrustes`]: Procrustes disparity between two embeddings.
//! * [`spec`]: `pca:<model.bin>?…` material specs (points of a model's space as materials).

#![warn(missing_docs)]

pub mod charting;
pub mod corpus;
pub mod error;
pub mod gram;
pub mod isomap;
pub mod lle;
pub mod mds;
pub mod model;
pub mod nmf;
pub mod pca;
pub mod plausibility;
#[cfg(feature = "plot")]
pub mod plot;
pub mod procrustes;
pub mod report;
pub mod spec;

pub use error::{ReduceError, Result};
