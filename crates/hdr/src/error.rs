//! Errors of the `hdr` crate.

use std::path::PathBuf;

/// Everything that can go wrong while merging exposures, building a defect map, planning a
/// bracket or reading and writing HDR files.
#[derive(Debug, thiserror::Error)]
pub enum HdrError {
    /// No frames were given to a merge.
    #[error("no frames to merge")]
    NoFrames,
    /// Frames (or a frame and a defect map) disagree in size.
    #[error("dimension mismatch: {0}")]
    Dimensions(String),
    /// A frame is internally inconsistent (data length, bit depth).
    #[error("malformed frame {index}: {detail}")]
    MalformedFrame {
        /// Position of the frame in the input slice.
        index: usize,
        /// What is wrong.
        detail: String,
    },
    /// An exposure time is not a positive finite number of seconds.
    #[error("frame {index}: exposure time {exposure_s} s is not positive and finite")]
    InvalidExposure {
        /// Position of the frame in the input slice.
        index: usize,
        /// The offending exposure time.
        exposure_s: f64,
    },
    /// The exposure times cannot determine the fit (e.g. fewer distinct times than unknowns).
    #[error("exposure series cannot determine the fit: {0}")]
    DegenerateSeries(String),
    /// An option is out of its domain.
    #[error("invalid option: {0}")]
    InvalidOption(String),
    /// The dark frame does not have the expected exposure.
    #[error("dark frame of {got_s} s, expected {expected_s} s")]
    DarkExposure {
        /// Exposure of the frame given.
        got_s: f64,
        /// Exposure the options ask for.
        expected_s: f64,
    },
    /// Reading or writing a file failed.
    #[error("I/O on {path}: {source}")]
    Io {
        /// The file concerned.
        path: PathBuf,
        /// The underlying error.
        #[source]
        source: std::io::Error,
    },
    /// The OpenEXR codec failed.
    #[error("OpenEXR {path}: {detail}")]
    Exr {
        /// The file concerned.
        path: PathBuf,
        /// The codec's message.
        detail: String,
    },
    /// An OpenEXR file lacks what an HDR file must contain, or contains malformed metadata.
    #[error("{path} is not an HDR radiance file: {detail}")]
    NotHdrFile {
        /// The file concerned.
        path: PathBuf,
        /// What is missing or malformed.
        detail: String,
    },
}

/// Result alias of the crate.
pub type HdrResult<T> = Result<T, HdrError>;
