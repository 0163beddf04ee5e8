//! Forward-mode automatic differentiation, re-exported from [`brdf::Real`]: the fitter
//! evaluates `brdf`'s analytic models on [`Dual`] numbers for exact parameter gradients.

pub use brdf::{Dual, Real};
