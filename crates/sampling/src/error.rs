//! Error type of the crate.

use std::path::PathBuf;

/// Everything that can go wrong while planning, measuring or reconstructing.
#[derive(Debug, thiserror::Error)]
pub enum SamplingError {
    /// File system failure.
    #[error("i/o error on {path}: {source}")]
    Io {
        /// File involved.
        path: PathBuf,
        /// Underlying error.
        source: std::io::Error,
    },
    /// A CSV file does not follow the plan / values format.
    #[error("malformed CSV {path} line {line}: {reason}")]
    MalformedCsv {
        /// File involved.
        path: PathBuf,
        /// 1-based line number.
        line: usize,
        /// What was wrong.
        reason: String,
    },
    /// Arrays or parameters with inconsistent sizes.
    #[error("dimension mismatch: {0}")]
    Dimension(String),
    /// A parameter outside its valid range.
    #[error("invalid parameter: {0}")]
    InvalidParameter(String),
    /// Non-finite input data.
    #[error("non-finite value: {0}")]
    NonFinite(String),
    /// Error from the `brdf` crate.
    #[error(transparent)]
    Brdf(#[from] brdf::BrdfError),
}

impl SamplingError {
    /// Wraps an i/o error with its path.
    pub fn io(path: impl Into<PathBuf>, source: std::io::Error) -> Self {
        SamplingError::Io {
            path: path.into(),
            source,
        }
    }
}

/// Result alias of the crate.
pub type Result<T> = std::result::Result<T, SamplingError>;
