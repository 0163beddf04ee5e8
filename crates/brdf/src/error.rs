//! Typed errors of the `brdf` crate.

use std::path::PathBuf;

/// Everything that can go wrong reading, writing or naming a BRDF.
#[derive(Debug, thiserror::Error)]
pub enum BrdfError {
    /// An I/O failure on a file.
    #[error("{path}: {io}")]
    Io {
        /// The file.
        path: PathBuf,
        /// The underlying error (its message is part of this error's message).
        io: std::io::Error,
    },
    /// A file ended before all expected bytes were read.
    #[error("{path}: truncated: expected {expected} bytes, found {found}")]
    Truncated {
        /// The file.
        path: PathBuf,
        /// Bytes the format requires.
        expected: u64,
        /// Bytes present.
        found: u64,
    },
    /// A file has more bytes than its header announces.
    #[error("{path}: {extra} trailing bytes after the data")]
    TrailingBytes {
        /// The file.
        path: PathBuf,
        /// Number of unexpected bytes.
        extra: u64,
    },
    /// A MERL header with dimensions other than 90 × 90 × 180.
    #[error("{path}: unsupported table dimensions {dims:?} (expected [90, 90, 180])")]
    BadDimensions {
        /// The file.
        path: PathBuf,
        /// Dimensions found in the header.
        dims: [i64; 3],
    },
    /// A value that is NaN or infinite.
    #[error("{path}: non-finite value at index {index}")]
    NonFinite {
        /// The file (or a description of the source).
        path: PathBuf,
        /// Flat index of the offending value.
        index: usize,
    },
    /// A malformed `.npy` file.
    #[error("{path}: malformed .npy file: {reason}")]
    Npy {
        /// The file.
        path: PathBuf,
        /// What is wrong.
        reason: String,
    },
    /// An array of the wrong shape.
    #[error("{what}: expected shape {expected:?}, found {found:?}")]
    Shape {
        /// What was being read.
        what: String,
        /// The shape required.
        expected: Vec<usize>,
        /// The shape found.
        found: Vec<usize>,
    },
    /// A material-spec string that cannot be understood.
    #[error("material spec '{spec}': {reason}")]
    Spec {
        /// The spec string.
        spec: String,
        /// What is wrong.
        reason: String,
    },
    /// A model parameter outside its valid range.
    #[error("{model}: invalid parameter {param} = {value} ({reason})")]
    Parameter {
        /// The model.
        model: String,
        /// The parameter name.
        param: String,
        /// The value given.
        value: f64,
        /// The constraint that failed.
        reason: String,
    },
    /// A material resolved by a registered [`crate::spec::SpecResolver`] failed to load.
    #[error("material spec '{spec}': {source}")]
    Resolver {
        /// The spec string.
        spec: String,
        /// The resolver's own error.
        #[source]
        source: Box<dyn std::error::Error + Send + Sync>,
    },
    /// A corpus that cannot be assembled (an input without materials, no inputs at all).
    #[error("corpus: {0}")]
    Corpus(String),
    /// Tables an error metric cannot compare (different grids, a non-finite estimate, an
    /// all-zero reference).
    #[error("error metric: {0}")]
    Metric(String),
    /// Wrong length of a raw value buffer.
    #[error("expected {expected} values, found {found}")]
    Length {
        /// Values required.
        expected: usize,
        /// Values given.
        found: usize,
    },
}

impl BrdfError {
    /// Wraps an I/O error with the path it concerns.
    pub fn io(path: impl Into<PathBuf>, io: std::io::Error) -> Self {
        Self::Io {
            path: path.into(),
            io,
        }
    }
}

/// Result alias of this crate.
pub type Result<T, E = BrdfError> = std::result::Result<T, E>;
