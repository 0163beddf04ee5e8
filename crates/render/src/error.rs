//! Error type of the renderer.

use std::path::PathBuf;

/// Everything that can go wrong while building or rendering a scene.
#[derive(Debug, thiserror::Error)]
pub enum RenderError {
    /// Reading or writing a file failed.
    #[error("I/O error on {path}: {source}")]
    Io {
        /// The file involved.
        path: PathBuf,
        /// The underlying error.
        #[source]
        source: std::io::Error,
    },
    /// A scene description could not be parsed or is inconsistent.
    #[error("scene description: {0}")]
    Scene(String),
    /// A Wavefront OBJ file is malformed.
    #[error("OBJ file {path}, line {line}: {message}")]
    Obj {
        /// The file.
        path: PathBuf,
        /// One-based line number.
        line: usize,
        /// What is wrong.
        message: String,
    },
    /// An OpenEXR file could not be read or written.
    #[error("OpenEXR {path}: {message}")]
    Exr {
        /// The file.
        path: PathBuf,
        /// The decoder's or encoder's message.
        message: String,
    },
    /// A Radiance `.hdr` (RGBE) file could not be read.
    #[error("Radiance HDR {path}: {message}")]
    Hdr {
        /// The file.
        path: PathBuf,
        /// What is wrong with it.
        message: String,
    },
    /// A PNG file could not be read or written.
    #[error("PNG {path}: {message}")]
    Png {
        /// The file.
        path: PathBuf,
        /// The decoder's or encoder's message.
        message: String,
    },
    /// A material could not be resolved from its description.
    #[error("material `{name}`: {message}")]
    Material {
        /// The material's name in the scene.
        name: String,
        /// What is wrong.
        message: String,
    },
    /// A process path file (`{"nodes": [[…], …]}`) is malformed.
    #[error("process path {path}: {message}")]
    ProcessPath {
        /// The file (empty for text that came from no file).
        path: PathBuf,
        /// What is wrong.
        message: String,
    },
    /// An argument is out of its valid range (wrong dimensions, NaN, negative sizes, ...).
    #[error("invalid argument: {0}")]
    InvalidArgument(String),
    /// A model file (`model.bin`) could not be read or used.
    #[error(transparent)]
    Model(#[from] reduce::ReduceError),
}

impl RenderError {
    pub(crate) fn io(path: impl Into<PathBuf>, source: std::io::Error) -> Self {
        Self::Io {
            path: path.into(),
            source,
        }
    }
}

/// Result alias of this crate.
pub type Result<T, E = RenderError> = std::result::Result<T, E>;
