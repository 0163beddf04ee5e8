//! Typed errors of the server.

use axum::http::StatusCode;
use axum::response::{IntoResponse, Response};

/// Result alias of this crate.
pub type Result<T, E = ServeError> = std::result::Result<T, E>;

/// Everything that can go wrong while serving a request or starting the server. Each maps to
/// an HTTP status and a JSON body `{"error": message, "kind": kebab-case-kind}` that the page
/// shows as it is.
#[derive(Debug, thiserror::Error)]
pub enum ServeError {
    /// A material name that is not a plain corpus name (path separators, `..`, control
    /// characters, or too long).
    #[error(
        "invalid material name {0:?}: names are letters, digits, '-', '_', '.' and ':' (no path)"
    )]
    InvalidName(String),
    /// No material of that name.
    #[error("no material named {0:?}")]
    UnknownMaterial(String),
    /// No route of that path.
    #[error("not found: {0}")]
    NotFound(String),
    /// No trait of that name in the loaded trait sets.
    #[error("no trait named {0:?}")]
    UnknownTrait(String),
    /// No edit session with that id (it ended or was evicted).
    #[error("no edit session {0} (it may have been closed to free memory; start a new one)")]
    UnknownSession(u64),
    /// Editing needs a model and a trait set.
    #[error("editing needs a model and a trait set: build them from the corpus (the page's button, or POST /api/editing/prepare), or start the server with --model and --traits")]
    EditingDisabled,
    /// The real-time view and coefficient queries need a model.
    #[error("the real-time view needs a model: start the server with --model")]
    NoModel,
    /// An upload larger than the limit.
    #[error("upload too large: more than the limit of {limit} bytes (a MERL .binary is 34,992,012 bytes)")]
    UploadTooLarge {
        /// The limit.
        limit: u64,
    },
    /// An upload that is not a valid MERL `.binary` file, or not a light probe.
    #[error("{message}")]
    BadUpload {
        /// What is wrong, for the page.
        message: String,
        /// `wrong-size`, `bad-header` or `non-finite` (materials), `bad-probe` (probes).
        kind: &'static str,
    },
    /// A query or body parameter out of range.
    #[error("invalid parameter: {0}")]
    InvalidParameter(String),
    /// An error of the material library.
    #[error(transparent)]
    Brdf(#[from] brdf::BrdfError),
    /// An error of the trait library.
    #[error(transparent)]
    Traits(#[from] traits::TraitsError),
    /// An error of the model library.
    #[error(transparent)]
    Reduce(#[from] reduce::ReduceError),
    /// An error of the renderer.
    #[error(transparent)]
    Render(#[from] render::RenderError),
    /// PNG encoding failed.
    #[error("PNG encoding: {0}")]
    Png(String),
    /// A socket or file failure of the server itself.
    #[error("{what}: {source}")]
    Io {
        /// What was being done.
        what: String,
        /// The failure.
        source: std::io::Error,
    },
    /// A background computation was cancelled or panicked.
    #[error("internal: {0}")]
    Internal(String),
}

impl ServeError {
    /// The kebab-case kind sent to clients.
    pub fn kind(&self) -> &'static str {
        match self {
            ServeError::InvalidName(_) => "invalid-name",
            ServeError::UnknownMaterial(_) => "unknown-material",
            ServeError::UnknownTrait(_) => "unknown-trait",
            ServeError::NotFound(_) => "not-found",
            ServeError::UnknownSession(_) => "unknown-session",
            ServeError::EditingDisabled => "editing-disabled",
            ServeError::NoModel => "no-model",
            ServeError::UploadTooLarge { .. } => "too-large",
            ServeError::BadUpload { kind, .. } => kind,
            ServeError::InvalidParameter(_) => "invalid-parameter",
            ServeError::Traits(traits::TraitsError::InvalidStart(_)) => "invalid-start",
            ServeError::Brdf(_) => "material",
            ServeError::Traits(_) => "traits",
            ServeError::Reduce(_) => "model",
            ServeError::Render(_) => "render",
            ServeError::Png(_) | ServeError::Io { .. } | ServeError::Internal(_) => "internal",
        }
    }

    /// The HTTP status of the error.
    pub fn status(&self) -> StatusCode {
        match self {
            ServeError::InvalidName(_)
            | ServeError::InvalidParameter(_)
            | ServeError::UnknownTrait(_) => StatusCode::BAD_REQUEST,
            ServeError::UnknownMaterial(_)
            | ServeError::UnknownSession(_)
            | ServeError::NotFound(_) => StatusCode::NOT_FOUND,
            ServeError::EditingDisabled | ServeError::NoModel => StatusCode::CONFLICT,
            ServeError::UploadTooLarge { .. } => StatusCode::PAYLOAD_TOO_LARGE,
            ServeError::BadUpload { .. } => StatusCode::UNPROCESSABLE_ENTITY,
            ServeError::Traits(traits::TraitsError::InvalidStart(_)) => {
                StatusCode::UNPROCESSABLE_ENTITY
            }
            _ => StatusCode::INTERNAL_SERVER_ERROR,
        }
    }

    /// The error of a malformed MERL upload, with a message for people.
    pub fn from_merl(e: brdf::BrdfError) -> ServeError {
        use brdf::BrdfError as B;
        let (message, kind) = match &e {
            B::Truncated {
                expected, found, ..
            } => {
                (
                    if *found < 12 {
                        format!("not a MERL .binary file: {found} bytes, shorter than the 12-byte header")
                    } else {
                        format!("wrong size: the header announces {expected} bytes, the file has {found}")
                    },
                    "wrong-size",
                )
            }
            B::TrailingBytes { extra, .. } => (
                format!("wrong size: {extra} bytes after the end of the table"),
                "wrong-size",
            ),
            B::BadDimensions { dims, .. } => (
                format!(
                    "bad header: dimensions {} × {} × {} (a MERL table is 90 × 90 × 180)",
                    dims[0], dims[1], dims[2]
                ),
                "bad-header",
            ),
            B::NonFinite { index, .. } => (
                format!(
                    "the table holds NaN or infinity (value {index} of {}, channel {})",
                    3 * brdf::BINS,
                    index / brdf::BINS
                ),
                "non-finite",
            ),
            other => (other.to_string(), "bad-file"),
        };
        ServeError::BadUpload { message, kind }
    }
}

impl IntoResponse for ServeError {
    fn into_response(self) -> Response {
        let status = self.status();
        if status.is_server_error() {
            tracing::warn!(error = %self, "request failed");
        }
        let body = serde_json::json!({ "error": self.to_string(), "kind": self.kind() });
        (status, axum::Json(body)).into_response()
    }
}
