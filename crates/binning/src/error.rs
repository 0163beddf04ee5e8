//! Typed errors of the binning crate.

use std::path::PathBuf;

/// What can go wrong while binning.
#[derive(Debug, thiserror::Error)]
pub enum BinningError {
    /// An I/O failure on a file.
    #[error("{path}: {io}")]
    Io {
        /// The file.
        path: PathBuf,
        /// The underlying error.
        io: std::io::Error,
    },
    /// A sample file that does not follow the format.
    #[error("{path}: malformed sample file: {reason}")]
    Malformed {
        /// The file.
        path: PathBuf,
        /// What is wrong.
        reason: String,
    },
    /// Inputs whose sizes do not agree.
    #[error("dimension mismatch: {0}")]
    Dimensions(String),
    /// A parameter outside its valid range.
    #[error("invalid parameter: {0}")]
    Parameter(String),
    /// An error from the brdf crate.
    #[error(transparent)]
    Brdf(#[from] brdf::BrdfError),
}

impl BinningError {
    pub(crate) fn io(path: impl Into<PathBuf>, io: std::io::Error) -> Self {
        Self::Io {
            path: path.into(),
            io,
        }
    }
}

/// Result alias of this crate.
pub type Result<T, E = BinningError> = std::result::Result<T, E>;
