//! # reduce — linear and non-linear models of the space of measured BRDFs
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
