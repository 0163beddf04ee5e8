//! Errors of the trait and navigation code.

use std::path::PathBuf;

/// Everything that can go wrong in this crate.
#[derive(Debug, thiserror::Error)]
pub enum TraitsError {
    /// A label or rating file could not be parsed.
    #[error("{path}:{line}: {message}")]
    Parse {
        /// File (or `<memory>`).
        path: PathBuf,
        /// 1-based line number.
        line: usize,
        /// What is wrong.
        message: String,
    },
    /// A labelled material is not in the model's corpus.
    #[error("unknown material {0:?} (not in the model's corpus)")]
    UnknownMaterial(String),
    /// A trait name that the label set or trait set does not define.
    #[error("unknown trait {0:?}")]
    UnknownTrait(String),
    /// A trait has too few labels of one class to define a direction.
    #[error("trait {name:?} has {present} present and {absent} absent labels; each class needs at least {min}")]
    TooFewLabels {
        /// Trait name.
        name: String,
        /// Materials labelled present.
        present: usize,
        /// Materials labelled absent.
        absent: usize,
        /// Required per class.
        min: usize,
    },
    /// Inconsistent sizes.
    #[error("dimension mismatch in {what}: expected {expected}, got {got}")]
    Dimension {
        /// What was being sized.
        what: &'static str,
        /// Expected size.
        expected: usize,
        /// Size found.
        got: usize,
    },
    /// An argument out of its domain.
    #[error("invalid parameter: {0}")]
    InvalidParameter(String),
    /// The model lacks a part that the operation needs (e.g. the chart).
    #[error("the model has no {0}")]
    MissingModelPart(&'static str),
    /// A numerical step failed.
    #[error("numerical failure: {0}")]
    Numerical(String),
    /// The starting point of a navigation already fails a validity check.
    #[error("the starting point is not physically valid: {0}")]
    InvalidStart(String),
    /// I/O.
    #[error("{path}: {source}")]
    Io {
        /// File.
        path: PathBuf,
        /// Cause.
        source: std::io::Error,
    },
    /// JSON (de)serialisation of a trait set.
    #[error("trait set JSON: {0}")]
    Json(#[from] serde_json::Error),
    /// From the model crate.
    #[error(transparent)]
    Reduce(#[from] reduce::ReduceError),
    /// From the BRDF crate.
    #[error(transparent)]
    Brdf(#[from] brdf::BrdfError),
}

impl TraitsError {
    pub(crate) fn io(path: impl Into<PathBuf>, source: std::io::Error) -> Self {
        TraitsError::Io {
            path: path.into(),
            source,
        }
    }
}

/// Result alias.
pub type Result<T> = std::result::Result<T, TraitsError>;
