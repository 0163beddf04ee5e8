//! Errors of the measurement job.

use std::path::PathBuf;

/// Why a measurement job stopped. Every variant that concerns a file names it.
#[derive(Debug, thiserror::Error)]
pub enum AcquireError {
    /// The job's parameters are unusable.
    #[error("invalid job: {0}")]
    InvalidJob(String),
    /// The thread that writes each captured position (HDR image, samples, seal) ended without
    /// an error of its own: it panicked, a fault of this program rather than of the rig or the
    /// job. The positions sealed before it are kept and a resumed job captures the rest.
    #[error("the position writer stopped unexpectedly while writing position files; the positions sealed so far are kept (resume the job)")]
    WriterStopped,
    /// The output directory holds another job, or a job with other parameters.
    #[error("{path}: {reason}")]
    JobDirectory {
        /// The directory or its `job.json`.
        path: PathBuf,
        /// What is wrong.
        reason: String,
    },
    /// Another running process holds the job directory's lock.
    #[error("{path}: the job directory is in use by a running job (pid {pid}); wait for it to end or stop it")]
    Locked {
        /// The lock file.
        path: PathBuf,
        /// The process holding it.
        pid: u32,
    },
    /// A file could not be read or written.
    #[error("{path}: {source}")]
    Io {
        /// The file.
        path: PathBuf,
        /// The operating system's error.
        source: std::io::Error,
    },
    /// A JSON file of the job directory is malformed.
    #[error("{path}: malformed: {reason}")]
    Malformed {
        /// The file.
        path: PathBuf,
        /// What the parser or the check said.
        reason: String,
    },
    /// A position's checkpoint is missing: the capture is incomplete.
    #[error("{0} is missing: the capture is incomplete (resume the job)")]
    Incomplete(PathBuf),
    /// A device kept failing after every retry the policy allows.
    #[error("{0}")]
    RetriesExhausted(String),
    /// A device reported an error the retry policy does not handle.
    #[error(transparent)]
    Device(#[from] gantry_hal::HalError),
    /// The simulator could not be built.
    #[cfg(feature = "sim")]
    #[error(transparent)]
    Simulator(#[from] hal_sim::SimError),
    /// Calibration failed or a calibration file is unusable.
    #[error(transparent)]
    Calibration(#[from] calib::CalibError),
    /// HDR merge or EXR I/O failed.
    #[error(transparent)]
    Hdr(#[from] hdr::HdrError),
    /// Binning or validation failed.
    #[error(transparent)]
    Binning(#[from] binning::BinningError),
    /// A material or table operation failed.
    #[error(transparent)]
    Brdf(#[from] brdf::BrdfError),
}

/// Result of the measurement job.
pub type Result<T, E = AcquireError> = std::result::Result<T, E>;

/// Shorthand for an I/O error on `path`.
pub(crate) fn io(path: impl Into<PathBuf>) -> impl FnOnce(std::io::Error) -> AcquireError {
    let path = path.into();
    move |source| AcquireError::Io { path, source }
}
