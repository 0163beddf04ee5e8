//! Typed errors of the `reduce` crate.

use std::path::PathBuf;

/// Everything that can go wrong while building, storing or applying a reflectance model.
#[derive(Debug, thiserror::Error)]
pub enum ReduceError {
    /// Underlying I/O failure.
    #[error("i/o error on {path}: {source}")]
    Io {
        /// File concerned.
        path: PathBuf,
        /// The OS error.
        #[source]
        source: std::io::Error,
    },
    /// An error from the `brdf` crate (reading tables, NBRDF weights, specs).
    #[error("brdf: {0}")]
    Brdf(#[from] brdf::BrdfError),
    /// Vectors or matrices whose sizes do not fit together.
    #[error("dimension mismatch: {what}: expected {expected}, got {got}")]
    Dimension {
        /// What was being checked.
        what: &'static str,
        /// Expected size.
        expected: usize,
        /// Size found.
        got: usize,
    },
    /// NaN or infinite value in the input.
    #[error("non-finite value in {0}")]
    NonFinite(&'static str),
    /// Too few samples / materials for the requested analysis.
    #[error("not enough data: {0}")]
    NotEnoughData(String),
    /// A parameter outside its valid range.
    #[error("invalid parameter: {0}")]
    InvalidParameter(String),
    /// A model file that is not a model file, has an unknown version or is truncated.
    #[error("malformed model file: {0}")]
    MalformedModel(String),
    /// The neighbourhood graph is disconnected and the chosen policy forbids that.
    #[error("neighbourhood graph has {components} connected components")]
    Disconnected {
        /// Number of connected components found.
        components: usize,
    },
    /// A numerical step failed (singular system, no positive eigenvalue, ...).
    #[error("numerical failure: {0}")]
    Numerical(String),
    /// Plot rendering failed.
    #[error("plot: {0}")]
    Plot(String),
}

/// Result alias of the crate.
pub type Result<T> = std::result::Result<T, ReduceError>;

impl ReduceError {
    pub(crate) fn io(path: impl Into<PathBuf>, source: std::io::Error) -> Self {
        ReduceError::Io {
            path: path.into(),
            source,
        }
    }
}

impl ReduceError {
    /// `Ok` when `got == expected`, else a [`ReduceError::Dimension`] error about `what`.
    pub(crate) fn check_size(what: &'static str, expected: usize, got: usize) -> Result<()> {
        if got == expected {
            Ok(())
        } else {
            Err(ReduceError::Dimension {
                what,
                expected,
                got,
            })
        }
    }
}
