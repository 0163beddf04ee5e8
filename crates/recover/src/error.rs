//! Errors of material recovery.

use std::path::PathBuf;
use thiserror::Error;

/// Everything that can go wrong while recovering a material from photographs.
#[derive(Debug, Error)]
pub enum RecoverError {
    /// A file could not be read or written.
    #[error("{path}: {source}")]
    Io {
        /// The file.
        path: PathBuf,
        /// The cause.
        source: std::io::Error,
    },
    /// An image file could not be decoded.
    #[error("cannot read image {path}: {message}")]
    Image {
        /// The file.
        path: PathBuf,
        /// What the decoder said.
        message: String,
    },
    /// The photograph's size differs from the scene camera's.
    #[error(
        "image {index} is {got_width}×{got_height} but the scene's camera renders \
         {width}×{height}"
    )]
    CameraMismatch {
        /// Index of the image among the observations.
        index: usize,
        /// Camera width.
        width: usize,
        /// Camera height.
        height: usize,
        /// Image width.
        got_width: usize,
        /// Image height.
        got_height: usize,
    },
    /// The object as seen by the camera does not line up with the bright part of the image.
    #[error("image {index} does not show the object where the scene's camera sees it: {message}")]
    Silhouette {
        /// Index of the image.
        index: usize,
        /// What was found.
        message: String,
    },
    /// No usable pixel is bright enough.
    #[error("image {index} is dark on the object: {message}")]
    AllDark {
        /// Index of the image.
        index: usize,
        /// What was found.
        message: String,
    },
    /// Every object pixel the lights reach is saturated (unlit pixels in shadow carry nothing).
    #[error("image {index} is saturated on the object ({saturated} of the {object} lit object pixels at or above {level})")]
    AllSaturated {
        /// Index of the image.
        index: usize,
        /// Saturated lit object pixels.
        saturated: usize,
        /// Lit object pixels.
        object: usize,
        /// The saturation level.
        level: f32,
    },
    /// The object is far brighter than a white diffuse surface under the scene's lights could
    /// be: the photograph's exposure (or the lights' intensity) does not match the scene.
    #[error(
        "image {index} is {ratio:.3e} times as bright on the object as a white diffuse surface \
         under the scene's lights (median over the lit pixels; at most {limit} is physical for \
         the materials the model describes): the photograph's exposure or the scene's light \
         intensities are wrong"
    )]
    Overexposed {
        /// Index of the image.
        index: usize,
        /// Median over lit, unsaturated object pixels of observed over white-surface radiance.
        ratio: f64,
        /// The largest ratio accepted.
        limit: f64,
    },
    /// The model is not a log-space model of full MERL tables.
    #[error("the model is of another grid: vectors of {got} values, expected {expected} (3 × 90 × 90 × 180)")]
    ModelGrid {
        /// Expected vector length.
        expected: usize,
        /// The model's vector length.
        got: usize,
    },
    /// The scene cannot be used for recovery.
    #[error("scene: {0}")]
    Scene(String),
    /// A parameter is out of range.
    #[error("invalid parameter: {0}")]
    InvalidParameter(String),
    /// The mask does not match the image.
    #[error("mask is {got_width}×{got_height}, image is {width}×{height}")]
    MaskMismatch {
        /// Image width.
        width: usize,
        /// Image height.
        height: usize,
        /// Mask width.
        got_width: usize,
        /// Mask height.
        got_height: usize,
    },
    /// The fit could not proceed (singular system, non-finite values).
    #[error("fit failed: {0}")]
    Fit(String),
    /// From the renderer.
    #[error(transparent)]
    Render(#[from] render::RenderError),
    /// From the model crate.
    #[error(transparent)]
    Reduce(#[from] reduce::ReduceError),
    /// From the BRDF crate.
    #[error(transparent)]
    Brdf(#[from] brdf::BrdfError),
}

impl RecoverError {
    /// An I/O error on `path`.
    pub fn io(path: impl Into<PathBuf>, source: std::io::Error) -> Self {
        RecoverError::Io {
            path: path.into(),
            source,
        }
    }
}

/// Result alias of this crate.
pub type Result<T> = std::result::Result<T, RecoverError>;
