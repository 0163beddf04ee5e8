//! The crate's error type.

use std::path::PathBuf;

/// Result of this crate.
pub type Result<T, E = FastError> = std::result::Result<T, E>;

/// What can go wrong while planning, capturing or completing a fast capture.
#[derive(Debug, thiserror::Error)]
pub enum FastError {
    /// The capture job failed (devices, calibration, HDR, binning, files).
    #[error(transparent)]
    Acquire(#[from] acquire::AcquireError),
    /// The model could not be applied.
    #[error(transparent)]
    Model(#[from] reduce::ReduceError),
    /// A material or table could not be read or written.
    #[error(transparent)]
    Brdf(#[from] brdf::BrdfError),
    /// The coverage of a lamp position could not be computed.
    #[error(transparent)]
    Binning(#[from] binning::BinningError),
    /// An option is out of range.
    #[error("invalid fast-capture option: {0}")]
    InvalidOption(String),
    /// The model does not describe full MERL tables.
    #[error("the model holds vectors of {dim} values, not full MERL tables ({expected}): build it on full tables")]
    ModelShape {
        /// Length of the model's vectors.
        dim: usize,
        /// Length of a MERL table.
        expected: usize,
    },
    /// A file could not be read or written.
    #[error("i/o error on {path}: {source}")]
    Io {
        /// File concerned.
        path: PathBuf,
        /// Underlying error.
        source: std::io::Error,
    },
    /// A stored plan or report could not be parsed.
    #[error("{path} is malformed: {reason}")]
    Malformed {
        /// File concerned.
        path: PathBuf,
        /// What is wrong.
        reason: String,
    },
    /// The stored plan belongs to another job.
    #[error("the plan stored in {path} does not match this job: {reason}")]
    PlanMismatch {
        /// The stored plan.
        path: PathBuf,
        /// What differs.
        reason: String,
    },
}

/// Maps an I/O error on `path`.
pub(crate) fn io(path: &std::path::Path) -> impl FnOnce(std::io::Error) -> FastError + '_ {
    move |source| FastError::Io {
        path: path.to_path_buf(),
        source,
    }
}
