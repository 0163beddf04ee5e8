//! Errors of the calibration procedures.

use std::path::PathBuf;

/// Everything that can go wrong while calibrating or reading/writing calibration files.
#[derive(Debug, thiserror::Error)]
pub enum CalibError {
    /// Fewer observations than the procedure needs.
    #[error("{what}: {got} given, at least {need} needed")]
    TooFewPoints {
        /// Which input.
        what: &'static str,
        /// Number supplied.
        got: usize,
        /// Minimum required.
        need: usize,
    },
    /// Too few target images showed the whole checkerboard: the others were dropped.
    #[error("the checkerboard was found whole in {usable} of {total} target images, at least {need} needed (dropped: {dropped})")]
    TooFewViews {
        /// Images in which every inner corner was found.
        usable: usize,
        /// Images given.
        total: usize,
        /// The minimum ([`crate::CalibrationOptions::min_views`], at least 3).
        need: usize,
        /// Each dropped image and why.
        dropped: String,
    },
    /// The observations do not constrain the unknowns (collinear, coplanar, coincident, ...).
    #[error("degenerate input: {0}")]
    Degenerate(String),
    /// An input value is NaN or infinite.
    #[error("non-finite value in {0}")]
    NonFinite(&'static str),
    /// An input value is out of its valid range.
    #[error("invalid input: {0}")]
    Invalid(String),
    /// The checkerboard was not found in a target image.
    #[error("checkerboard not found in image {image}: {reason}")]
    BoardNotFound {
        /// Index of the image in the input list.
        image: usize,
        /// What failed.
        reason: String,
    },
    /// Part of the checkerboard was found in a target image, not all of it.
    #[error("checkerboard incomplete in image {image}: {found} of {expected} corners")]
    TooFewCorners {
        /// Index of the image in the input list.
        image: usize,
        /// Corners in the largest lattice found.
        found: usize,
        /// Inner corners of the board.
        expected: usize,
        /// What failed.
        reason: String,
    },
    /// A non-linear fit did not converge to a usable solution.
    #[error("optimisation failed: {0}")]
    NotConverged(String),
    /// Calibration file of an unsupported schema version.
    #[error("calibration file version {found}, this build reads version {supported}")]
    Version {
        /// Version in the file.
        found: u32,
        /// Version this crate reads and writes.
        supported: u32,
    },
    /// Malformed file content.
    #[error("{path}: {detail}")]
    Parse {
        /// File concerned.
        path: PathBuf,
        /// What is wrong.
        detail: String,
    },
    /// JSON (de)serialisation error.
    #[error("JSON: {0}")]
    Json(#[from] serde_json::Error),
    /// PNG encoding/decoding error.
    #[error("image: {0}")]
    Image(#[from] image::ImageError),
    /// I/O error.
    #[error("I/O on {path}: {source}")]
    Io {
        /// File concerned.
        path: PathBuf,
        /// Underlying error.
        source: std::io::Error,
    },
}

/// A rig geometry that fails its checks: non-finite values stay [`CalibError::NonFinite`], the
/// violated constraints [`CalibError::Invalid`], with the same messages.
impl From<gantry_hal::GeometryError> for CalibError {
    fn from(e: gantry_hal::GeometryError) -> Self {
        match e {
            gantry_hal::GeometryError::NonFinite(what) => CalibError::NonFinite(what),
            gantry_hal::GeometryError::Invalid(detail) => CalibError::Invalid(detail),
        }
    }
}

/// Result alias of this crate.
pub type CalibResult<T> = Result<T, CalibError>;

/// Checks that all values are finite.
pub(crate) fn check_finite(what: &'static str, values: &[f64]) -> CalibResult<()> {
    if values.iter().all(|v| v.is_finite()) {
        Ok(())
    } else {
        Err(CalibError::NonFinite(what))
    }
}
