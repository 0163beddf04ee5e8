//! Typed errors of the `wavelet` crate.

/// Everything that can go wrong building cubes, transforms, bases and trees.
#[derive(Debug, thiserror::Error, PartialEq)]
pub enum WaveletError {
    /// A cube side that is not a power of two (or is zero).
    #[error("cube side {0} is not a power of two >= 2")]
    NotPowerOfTwo(usize),
    /// A slice whose length does not match what the operation expects.
    #[error("wrong length: expected {expected} values, found {found}")]
    Length {
        /// Expected number of values.
        expected: usize,
        /// Number of values received.
        found: usize,
    },
    /// A table extent that does not fit into the cube.
    #[error("table extent {extent:?} does not fit into a cube of side {side}")]
    ExtentTooLarge {
        /// Extent (θh, θd, φd) of the table.
        extent: [usize; 3],
        /// Side of the cube.
        side: usize,
    },
    /// A NaN or infinite input value.
    #[error("non-finite value at index {index}")]
    NonFinite {
        /// Flat index of the first offending value.
        index: usize,
    },
    /// More decomposition levels than the cube supports.
    #[error("{levels} levels requested but a cube of side {side} supports at most {max}")]
    TooManyLevels {
        /// Requested levels.
        levels: u32,
        /// Cube side.
        side: usize,
        /// Maximum number of levels, log2(side).
        max: u32,
    },
    /// A relative-error target outside `[0, 1]` or not finite.
    #[error("relative error target {0} is not in [0, 1]")]
    BadErrorTarget(f64),
    /// A coefficient index outside the cube.
    #[error("coefficient index {index} outside a cube of {len} coefficients")]
    IndexOutOfRange {
        /// Offending index.
        index: usize,
        /// Number of coefficients in the cube.
        len: usize,
    },
    /// An operation that needs at least one represented function got none.
    #[error("no functions given")]
    NoFunctions,
    /// An operation that does not support the chosen wavelet filter.
    #[error("unsupported wavelet: {0}")]
    UnsupportedWavelet(&'static str),
    /// A malformed basis file.
    #[error("malformed basis file: {0}")]
    Format(String),
    /// A file could not be read or written.
    #[error("i/o error: {0}")]
    Io(String),
    /// Two objects built for different cube sides.
    #[error("cube side mismatch: {0} vs {1}")]
    SideMismatch(usize, usize),
}

/// Result alias of the crate.
pub type Result<T> = std::result::Result<T, WaveletError>;
