//! # traits — user-defined parameterization of the space of measured BRDFs
//!
//! Thesis chapter 5: pick a measured material and turn dials named after what people see —
//! metallic, glossy, red — with every result physically valid.
//!
//! The work flows from labels to directions to valid edits:
//!
//! 1. **Label.** A [`LabelSet`] holds binary trait labels (present / absent / unspecified) and a
//!    [`RatingSet`] graded ratings ([`Table`] is the CSV file of either); [`thesis_labels`] is the
//!    shipped set of the thesis's 16 traits for the 96 shared MERL materials.
//! 2. **Find directions.** [`fit_binary`] turns labelled points of a model's space into a
//!    calibrated [`Direction`] by mean difference (thesis eq. 5.1), regularised Fisher
//!    discriminant (5.9) or soft-margin SVM (5.12–5.17) ([`Method`]); ridge regression fits
//!    ratings. [`SetFit`] fits whole trait sets into a [`TraitSet`] and cross-validates them
//!    (sign accuracy, leave-one-out Spearman ρ, [`angles`] between methods).
//! 3. **Stay valid.** [`validate`] checks non-negativity, reciprocity and directional albedo
//!    ≤ 1 ([`AlbedoQuadrature`]), and [`in_convex_hull`] the convex hull of the corpus
//!    (thesis §5.2).
//! 4. **Navigate.** A [`Navigator`] applies edits in the linear or chart [`Space`] that stop at
//!    the border of the valid set, and walks process paths (thesis §5.4); a [`Session`] is the
//!    editor's fast path (one pass over the table per slider move), and [`SpherePreview`]
//!    shades a lit-sphere preview from a session's back-projection.
//!
//! [`FitJob`], [`ScoreJob`], [`PathJob`] and [`EditJob`] are the jobs behind `gantry traits` and
//! `gantry edit`, each options in, `run()`, a serde report out. [`fit_binary`] and [`FitJob`]
//! have worked examples.
//!
//! # Examples
//!
//! ```
//! use nalgebra::DMatrix;
//! use traits::{fit_binary, FitOptions, Method};
//!
//! // Six materials in a 3-D model space, labelled for a trait that grows along the second axis.
//! let x = DMatrix::from_row_slice(6, 3, &[
//!     0.2, 2.0, 0.1, -0.3, 2.5, 0.0, 0.1, 1.8, -0.2, // present
//!     0.0, -1.0, 0.1, 0.4, -1.5, 0.2, -0.2, -0.8, 0.0, // absent
//! ]);
//! let present = [true, true, true, false, false, false];
//! for method in [Method::Mean, Method::Fisher, Method::Svm] {
//!     let d = fit_binary(&x, &present, method, &FitOptions::default()).unwrap();
//!     // every labelled material falls on its side of the calibrated threshold
//!     for (i, &p) in present.iter().enumerate() {
//!         let row: Vec<f64> = x.row(i).iter().copied().collect();
//!         assert_eq!(d.score(&row) > d.threshold, p, "{method:?}, material {i}");
//!     }
//! }
//! ```

#![warn(missing_docs)]
#![allow(clippy::needless_range_loop)]

mod direction;
mod error;
mod job;
mod labels;
mod navigate;
mod preview;
mod select;
mod study;
mod validity;

pub use direction::fit_binary;
pub use labels::{serrano_ratings_path, thesis_labels, Table, MIN_PER_CLASS};
pub use navigate::{
    path_points, reconstruct_log, PathKind, State, BISECTION_STEPS, CHART_MARCH_STEPS,
    CHART_PCA_MARGIN,
};
pub use preview::SpherePreview;
pub use select::{nested_loo_scores, select_ridge, RidgeVariant, VARIANT_DIMS, VARIANT_LAMBDAS};
pub use study::{
    angles, loo_kernel_ridge_predictions, loo_kernel_ridge_scores, loo_ridge_predictions,
    loo_ridge_scores, rated_rows, spearman, KernelRidge, KernelRidgeGrid, SetFit,
};

pub use direction::{Direction, FitOptions, Method, RIDGE_GRID};
pub use error::{Result, TraitsError};
pub use job::{
    coords_of, default_trait_sets, EditJob, EditReport, FitJob, FitReport, PathJob, PathReport,
    PathStep, ScoreJob, ScoreReport, MIN_RATED,
};
pub use labels::{Label, LabelSet, RatingSet};
pub use navigate::{
    EditOutcome, Embedding, Navigator, NavigatorOptions, Session, Space, TraitSet, TraitVector,
};
pub use validity::{
    in_convex_hull, validate, AlbedoQuadrature, Check, ValidityOptions, ValidityReport,
};
