//! # traits — user-defined parameterization of the space of measured BRDFs
//!
//! Thesis chapter 5: pick a measured material and turn dials named after what people see —
//! metallic, glossy, red — with every result physically valid.
//!
//! * [`labels`]: binary trait labels (present / absent / unspecified) and graded ratings, and
//!   the shipped label set of the thesis's 16 traits for the 96 shared MERL materials.
//! * [`direction`]: trait vectors by mean difference (5.1), regularised Fisher discriminant
//!   (5.9), soft-margin SVM (5.12–5.17) and ridge regression onto ratings.
//! * [`study`]: cross-validation — sign accuracy, leave-one-out Spearman ρ, angles.
//! * [`validity`]: non-negativity, reciprocity, directional albedo ≤ 1 and the convex hull.
//! * [`navigate`]: spaces, trait sets, edits that stop at the border of the valid set, and
//!   process paths (§5.4); [`navigate::Session`] is the editor's fast path (one pass over
//!   the table per slider move).
//! * [`FitJob`], [`ScoreJob`], [`PathJob`], [`EditJob`]: the jobs behind `gantry traits` and
//!   `gantry edit`, each options in, `run()`, a serde report out.
//! * [`preview`]: the bins of a lit-sphere preview, shaded from a session's back-projection.
//!
//! ```
//! use nalgebra::DMatrix;
//! use traits::direction::{fit_binary, FitOptions, Method};
//!
//! // Four materials in a 2-D space; the trait is present where the first coordinate is large.
//! let x = DMatrix::from_row_slice(4, 2, &[2.0, 0.1, 3.0, -0.2, -1.0, 0.3, -2.0, 0.0]);
//! let present = [true, true, false, false];
//! let w = fit_binary(&x, &present, Method::Svm, &FitOptions::default()).unwrap();
//! // Scores are calibrated: 1 for the average material with the trait, 0 without it.
//! assert!(w.score(&[2.5, 0.0]) > w.threshold && w.score(&[-1.5, 0.0]) < w.threshold);
//! // One unit of the trait added to a point raises its score by one.
//! let step = w.unit_step();
//! let moved = [0.0 + step[0], 0.0 + step[1]];
//! assert!((w.score(&moved) - w.score(&[0.0, 0.0]) - 1.0).abs() < 1e-9);
//! ```

#![warn(missing_docs)]
#![allow(clippy::needless_range_loop)]

pub mod direction;
pub mod error;
mod job;
pub mod labels;
pub mod navigate;
pub mod preview;
pub mod study;
pub mod validity;

pub use direction::{Direction, FitOptions, Method};
pub use error::{Result, TraitsError};
pub use job::{
    coords_of, EditJob, EditReport, FitJob, FitReport, PathJob, PathReport, PathStep, ScoreJob,
    ScoreReport,
};
pub use labels::{Label, LabelSet, RatingSet};
pub use navigate::{
    EditOutcome, Embedding, Navigator, NavigatorOptions, Session, Space, TraitSet, TraitVector,
};
pub use validity::{validate, AlbedoQuadrature, Check, ValidityOptions, ValidityReport};
