//! Errors of reading and writing `.bsdf` files.

/// Result of this crate.
pub type Result<T> = std::result::Result<T, RglError>;

/// What went wrong with a tensor file or a `.bsdf` material.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum RglError {
    /// The file could not be read or written.
    #[error("{path}: {source}")]
    Io {
        /// The file.
        path: String,
        /// The cause.
        source: std::io::Error,
    },
    /// The header is not that of a tensor file, or is truncated or inconsistent.
    #[error("invalid tensor file: {0}")]
    Header(String),
    /// A field's declaration or data is invalid.
    #[error("invalid field '{field}': {reason}")]
    Field {
        /// The field's name.
        field: String,
        /// What is wrong.
        reason: String,
    },
    /// A field the `.bsdf` layout requires is absent.
    #[error("missing field '{0}'")]
    MissingField(String),
    /// The fields do not fit together as a `.bsdf` material (shapes, parameter values).
    #[error("not a valid .bsdf material: {0}")]
    Layout(String),
    /// Writer options out of range.
    #[error("invalid options: {0}")]
    Options(String),
    /// The source material could not be evaluated.
    #[error(transparent)]
    Brdf(#[from] brdf::BrdfError),
}
