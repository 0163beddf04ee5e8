//! Errors of the corpus store.

/// Errors of [`crate`].
#[derive(Debug, thiserror::Error)]
pub enum StoreError {
    /// The Zarr library reported an error (metadata, codec or storage).
    #[error("zarr: {context}: {source}")]
    Zarr {
        /// What was being done.
        context: String,
        /// The error of the Zarr library.
        #[source]
        source: Box<dyn std::error::Error + Send + Sync>,
    },
    /// A file-system error outside the Zarr library.
    #[error("{path}: {source}")]
    Io {
        /// The path involved.
        path: String,
        /// The I/O error.
        #[source]
        source: std::io::Error,
    },
    /// The store exists but is not a corpus store of this format, or is inconsistent.
    #[error("{path}: not a valid corpus store: {reason}")]
    Format {
        /// The store path.
        path: String,
        /// What is wrong.
        reason: String,
    },
    /// The store was not completely packed (resume `gantry corpus pack`).
    #[error("{path}: incomplete store: {missing} of {total} chunks missing (resume the pack)")]
    Incomplete {
        /// The store path.
        path: String,
        /// Missing chunks.
        missing: usize,
        /// All chunks.
        total: usize,
    },
    /// A chunk file exists but does not decode: its checksum does not match, it is truncated,
    /// or it holds the wrong number of values. Re-running the pack to the same store re-packs it.
    #[error("{path}: chunk {}/{} is damaged ({reason}); resume the pack to re-pack it", chunk.0, chunk.1)]
    Damaged {
        /// The store path.
        path: String,
        /// The chunk's (material block, bin block) index.
        chunk: (usize, usize),
        /// What the decoder found.
        reason: String,
    },
    /// An invalid argument (sizes, ranges, options).
    #[error("invalid parameter: {0}")]
    InvalidParameter(String),
    /// A synthetic material failed a physical validity check.
    #[error("synthetic material {index} is not physically valid: {reason}")]
    Invalid {
        /// Index of the material.
        index: usize,
        /// The failed check.
        reason: String,
    },
    /// An error of the `brdf` crate (decoding materials).
    #[error(transparent)]
    Brdf(#[from] brdf::BrdfError),
    /// An error of the `sampling` crate (reduced grids).
    #[error(transparent)]
    Sampling(#[from] sampling::SamplingError),
    /// An error of the out-of-core PCA or of the model file.
    #[error(transparent)]
    Reduce(#[from] reduce::ReduceError),
}

/// Result alias of this crate.
pub type Result<T, E = StoreError> = std::result::Result<T, E>;

pub(crate) fn zarr<E: std::error::Error + Send + Sync + 'static>(
    context: impl Into<String>,
) -> impl FnOnce(E) -> StoreError {
    let context = context.into();
    move |e| StoreError::Zarr {
        context,
        source: Box::new(e),
    }
}

pub(crate) fn io(path: &std::path::Path) -> impl FnOnce(std::io::Error) -> StoreError + '_ {
    move |source| StoreError::Io {
        path: path.display().to_string(),
        source,
    }
}
