//! Errors of the fitting library.

/// Everything that can go wrong while fitting.
#[derive(Debug, thiserror::Error)]
pub enum FitError {
    /// A model name that is not one of [`crate::ModelKind::ALL`] (or an unsupported lobe count).
    #[error("unknown model '{0}'")]
    UnknownModel(String),
    /// An objective name other than `log`, `ngan`, `sphere`.
    #[error("unknown objective '{0}' (expected log, ngan or sphere)")]
    UnknownObjective(String),
    /// The measured table has no usable bins for the objective.
    #[error("no valid data to fit: {0}")]
    NoData(String),
    /// An invalid option.
    #[error("invalid option: {0}")]
    Option(String),
    /// An error from the BRDF library (loading a material, parsing a spec).
    #[error(transparent)]
    Brdf(#[from] brdf::BrdfError),
    /// An error from the sampling library (the rendered-sphere metric).
    #[error(transparent)]
    Sampling(#[from] sampling::SamplingError),
    /// A study file could not be written.
    #[error("cannot write {path}: {source}")]
    Io {
        /// The file.
        path: std::path::PathBuf,
        /// The cause.
        source: std::io::Error,
    },
}

/// Result alias of the crate.
pub type Result<T> = std::result::Result<T, FitError>;
