//! Forward-mode automatic differentiation, re-exported from [`brdf::real`]: the fitter
//! evaluates `brdf`'s analytic models on [`Dual`] numbers for exact parameter gradients.

pub use brdf::real::{Dual, Real};
