//! The one error type of every device call.

use std::time::Duration;

/// Which device of the rig an error concerns.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum DeviceKind {
    /// The turntable carrying the lamp arm.
    Turntable,
    /// The light source.
    Lamp,
    /// The camera.
    Camera,
    /// The motion controller (GRBL board) driving turntable and lamp.
    MotionController,
    /// A USB device looked for during discovery.
    Usb,
    /// The contact digitizer.
    Digitizer,
}

impl std::fmt::Display for DeviceKind {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let s = match self {
            DeviceKind::Turntable => "turntable",
            DeviceKind::Lamp => "lamp",
            DeviceKind::Camera => "camera",
            DeviceKind::MotionController => "motion controller",
            DeviceKind::Usb => "USB device",
            DeviceKind::Digitizer => "digitizer",
        };
        f.write_str(s)
    }
}

/// Errors of the hardware abstraction layer. Every fault the simulator injects maps to one of
/// these variants, exactly as the real drivers report them.
///
/// The variants carry what a person needs to read (which device, which command, what the
/// operating system said); [`HalError::kind`] gives the [`ErrorKind`] a program decides on.
///
/// # Examples
///
/// ```
/// use gantry_hal::{DeviceKind, ErrorKind, HalError};
/// use std::time::Duration;
///
/// let err = HalError::Timeout {
///     device: DeviceKind::Camera,
///     operation: "capture".into(),
///     after: Duration::from_secs(5),
/// };
/// assert_eq!(err.kind(), ErrorKind::Timeout);
/// // a lost position and a turntable never homed call for the same remedy
/// let lost = HalError::LostPosition { detail: "hard limit".into() };
/// assert_eq!(lost.kind(), HalError::NotHomed.kind());
/// assert_eq!(lost.kind(), ErrorKind::NeedsHoming);
/// ```
#[derive(Debug, thiserror::Error)]
pub enum HalError {
    /// A device that the configuration names is not there (no such port, no camera, no USB id).
    #[error("{device} '{name}' is not available: {detail}")]
    DeviceAbsent {
        /// Kind of device.
        device: DeviceKind,
        /// The name the configuration used (port path, camera index, vid:pid).
        name: String,
        /// What the operating system or driver said.
        detail: String,
    },
    /// A blocking call did not complete in time.
    #[error("{device}: {operation} timed out after {after:?}")]
    Timeout {
        /// Kind of device.
        device: DeviceKind,
        /// What was being done.
        operation: String,
        /// The timeout that elapsed.
        after: Duration,
    },
    /// The turntable no longer knows where it is (lost steps, alarm); it must be homed again.
    #[error("turntable lost its position: {detail}")]
    LostPosition {
        /// What happened.
        detail: String,
    },
    /// The turntable has not been homed since power-up or since it lost its position.
    #[error("turntable is not homed")]
    NotHomed,
    /// The device went away (cable, power, USB reset). Reconnect before further use.
    #[error("{device} disconnected: {detail}")]
    Disconnected {
        /// Kind of device.
        device: DeviceKind,
        /// What happened.
        detail: String,
    },
    /// The camera did not deliver a frame for a trigger.
    #[error("camera dropped frame {frame_number}")]
    FrameDropped {
        /// Sequence number of the frame that was lost.
        frame_number: u64,
    },
    /// A frame arrived but failed validation.
    #[error("corrupted frame: {detail}")]
    CorruptedFrame {
        /// Which check failed.
        detail: String,
    },
    /// The lamp went dark while it should have been on.
    #[error("lamp dropout at t = {at_s:.3} s")]
    LampDropout {
        /// Rig time of the dropout, seconds.
        at_s: f64,
    },
    /// The lamp output changed while frames were being captured.
    #[error("lamp flicker: output changed by {relative_change:+.3} at t = {at_s:.3} s")]
    LampFlicker {
        /// Relative change of the radiant intensity.
        relative_change: f64,
        /// Rig time of the change, seconds.
        at_s: f64,
    },
    /// The lamp is off or still warming up when stable light is needed.
    #[error("lamp is not stable: {detail}")]
    LampNotStable {
        /// Current lamp state.
        detail: String,
    },
    /// The motion controller answered `error:N`.
    #[error("GRBL error {code}: {message} (command '{command}')")]
    GrblError {
        /// GRBL error code.
        code: u8,
        /// Meaning of the code.
        message: String,
        /// The command that was rejected.
        command: String,
    },
    /// The motion controller raised `ALARM:N`.
    #[error("GRBL alarm {code}: {message}")]
    GrblAlarm {
        /// GRBL alarm code.
        code: u8,
        /// Meaning of the code.
        message: String,
    },
    /// The device answered something that does not fit the protocol.
    #[error("{device} protocol error: {detail}")]
    Protocol {
        /// Kind of device.
        device: DeviceKind,
        /// What was received.
        detail: String,
    },
    /// An argument is out of the device's range (exposure, angle, speed).
    #[error("invalid argument: {0}")]
    InvalidArgument(String),
    /// Malformed pixel data (wrong length, wrong dimensions).
    #[error("invalid pixel data: {0}")]
    InvalidPixelData(String),
    /// The rig configuration could not be read or is inconsistent.
    #[error("rig configuration: {0}")]
    Config(String),
    /// The build lacks a feature the configuration asks for.
    #[error("feature '{feature}' is not compiled in (needed for {what})")]
    FeatureMissing {
        /// Cargo feature name.
        feature: &'static str,
        /// What needed it.
        what: String,
    },
    /// Operating-system I/O error.
    #[error("I/O error on {device}: {source}")]
    Io {
        /// Kind of device.
        device: DeviceKind,
        /// The underlying error.
        #[source]
        source: std::io::Error,
    },
}

/// What went wrong with a device call, independent of the driver (after embedded-hal's
/// `ErrorKind`): what a caller's retry policy matches on. More kinds may be added.
#[non_exhaustive]
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum ErrorKind {
    /// The device is not there ([`HalError::DeviceAbsent`]).
    Absent,
    /// A blocking call did not complete in time.
    Timeout,
    /// The turntable must be homed before it can move (lost position, never homed, or a
    /// controller that locks commands out until it is homed).
    NeedsHoming,
    /// The device went away; reconnect before further use.
    Disconnected,
    /// The camera did not deliver a frame.
    FrameDropped,
    /// A frame arrived but failed validation.
    CorruptedFrame,
    /// The lamp went dark while it should have been on.
    LampDropout,
    /// The lamp output changed while frames were being captured.
    LampFlicker,
    /// The lamp is off or still warming up.
    LampNotStable,
    /// The device answered something that does not fit its protocol.
    Protocol,
    /// The controller rejected a command (other than for want of homing).
    Rejected,
    /// The controller raised an alarm that does not lose its position.
    Alarm,
    /// An argument is out of the device's range.
    InvalidArgument,
    /// Malformed pixel data.
    InvalidData,
    /// The rig configuration is unusable, or the build lacks a feature it asks for.
    Config,
    /// Operating-system I/O error.
    Io,
}

impl HalError {
    /// The kind of this error, which is what a retry policy decides on.
    pub fn kind(&self) -> ErrorKind {
        match self {
            HalError::DeviceAbsent { .. } => ErrorKind::Absent,
            HalError::Timeout { .. } => ErrorKind::Timeout,
            HalError::LostPosition { .. } | HalError::NotHomed => ErrorKind::NeedsHoming,
            HalError::Disconnected { .. } => ErrorKind::Disconnected,
            HalError::FrameDropped { .. } => ErrorKind::FrameDropped,
            HalError::CorruptedFrame { .. } => ErrorKind::CorruptedFrame,
            HalError::LampDropout { .. } => ErrorKind::LampDropout,
            HalError::LampFlicker { .. } => ErrorKind::LampFlicker,
            HalError::LampNotStable { .. } => ErrorKind::LampNotStable,
            HalError::GrblError { code, .. } => crate::grbl::error_kind(*code),
            HalError::GrblAlarm { .. } => ErrorKind::Alarm,
            HalError::Protocol { .. } => ErrorKind::Protocol,
            HalError::InvalidArgument(_) => ErrorKind::InvalidArgument,
            HalError::InvalidPixelData(_) => ErrorKind::InvalidData,
            HalError::Config(_) | HalError::FeatureMissing { .. } => ErrorKind::Config,
            HalError::Io { .. } => ErrorKind::Io,
        }
    }
}

/// Result alias of the crate.
pub type HalResult<T> = Result<T, HalError>;
