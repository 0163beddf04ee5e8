//! The retry policy of the devices.

use crate::error::{AcquireError, Result};
use gantry_hal::{BayerFrame, ErrorKind, HalError, LampState, Rig};
use serde::{Deserialize, Serialize};
use std::time::Duration;

/// How long a turntable move may take before it counts as timed out.
pub const MOVE_TIMEOUT: Duration = Duration::from_secs(600);
/// How long the camera may take to deliver a frame.
pub const FRAME_TIMEOUT: Duration = Duration::from_secs(120);
/// How long the lamp may take to become stable.
pub const LAMP_TIMEOUT: Duration = Duration::from_secs(3600);
/// Attempts of one step before the job gives up.
pub const MAX_RETRIES: usize = 8;

/// The kinds of fault the retry policy handles.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum FaultKind {
    /// The turntable reported success but stands elsewhere; re-homed.
    TurntablePosition,
    /// The controller's answer was garbled or unexpected; retried.
    TurntableProtocol,
    /// A move timed out; retried.
    TurntableTimeout,
    /// The controller lost its position (alarm, not homed); re-homed.
    TurntableLost,
    /// The controller disconnected; reconnected and re-homed.
    TurntableDisconnect,
    /// A delivered frame failed its checks; taken again.
    FrameRejected,
    /// The camera dropped a frame or timed out; taken again.
    FrameDropped,
    /// The camera reported a corrupted frame; taken again.
    FrameCorrupted,
    /// The camera disconnected; reconnected.
    CameraDisconnect,
    /// The lamp was found off after a series; relit and the series repeated.
    LampOff,
    /// The lamp was not stable after a series; waited for and the series repeated.
    LampUnstable,
    /// The lamp dropped out during a series; relit and the series repeated.
    LampDropout,
    /// The lamp flickered during a series; the series was repeated.
    LampFlicker,
    /// The frames of a series disagree with their HDR fit (a change of light); repeated.
    SeriesInconsistent,
    /// A position's checkpoint on disk was unfinished, truncated or damaged (its seal did not
    /// verify) when the job resumed; the position was captured again.
    CheckpointDamaged,
}

impl FaultKind {
    /// The kebab-case name used in reports (`"frame-dropped"`).
    pub fn name(self) -> &'static str {
        match self {
            FaultKind::TurntablePosition => "turntable-position",
            FaultKind::TurntableProtocol => "turntable-protocol",
            FaultKind::TurntableTimeout => "turntable-timeout",
            FaultKind::TurntableLost => "turntable-lost",
            FaultKind::TurntableDisconnect => "turntable-disconnect",
            FaultKind::FrameRejected => "frame-rejected",
            FaultKind::FrameDropped => "frame-dropped",
            FaultKind::FrameCorrupted => "frame-corrupted",
            FaultKind::CameraDisconnect => "camera-disconnect",
            FaultKind::LampOff => "lamp-off",
            FaultKind::LampUnstable => "lamp-unstable",
            FaultKind::LampDropout => "lamp-dropout",
            FaultKind::LampFlicker => "lamp-flicker",
            FaultKind::SeriesInconsistent => "series-inconsistent",
            FaultKind::CheckpointDamaged => "checkpoint-damaged",
        }
    }
}

impl std::fmt::Display for FaultKind {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.name())
    }
}

/// One fault met and handled.
///
/// The retry policy of the devices: a fault a device reports (matched on its
/// [`gantry_hal::ErrorKind`]) is logged as a [`FaultEvent`],
/// handled (re-home, reconnect, relight, wait) and the step retried; any other error ends the
/// job, which can then be resumed.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct FaultEvent {
    /// What happened.
    pub kind: FaultKind,
    /// The attempt of the step (1-based) at which it happened, where the step is retried.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub attempt: Option<u32>,
    /// The device's message and what was done.
    pub detail: String,
}

impl std::fmt::Display for FaultEvent {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self.attempt {
            Some(a) => write!(f, "{}: attempt {a}: {}", self.kind, self.detail),
            None => write!(f, "{}: {}", self.kind, self.detail),
        }
    }
}

/// The device step [`Devices::retry`] repeats.
#[derive(Debug, Clone, Copy)]
enum Step {
    /// Turntable to this angle, degrees.
    Move(f64),
    /// Home the turntable.
    Home,
    /// A frame at this exposure, seconds.
    Frame(f64),
}

/// What the next attempt does before its step.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Recovery {
    /// Nothing: the step again.
    Retry,
    /// Home the turntable first.
    Home,
    /// Reconnect the device first (the turntable is then homed).
    Reconnect,
}

/// A fault of an attempt: what is logged and what the next attempt does first.
struct Noted {
    kind: FaultKind,
    /// Whether the log names the attempt.
    attempt: bool,
    detail: String,
    recovery: Recovery,
}

impl Noted {
    /// The policy: how a device error of `step` is handled, by its [`ErrorKind`]; an error
    /// the policy does not handle is returned.
    fn of(step: Step, e: HalError) -> Result<Noted> {
        let turntable = !matches!(step, Step::Frame(_));
        let homing = matches!(step, Step::Home);
        let (kind, attempt, suffix, recovery) = match (turntable, e.kind()) {
            // The axis may be held anywhere on the way: home before the next attempt (homing is
            // the step itself when it was homing).
            (true, ErrorKind::Timeout) => match homing {
                true => (FaultKind::TurntableTimeout, true, "", Recovery::Retry),
                false => (
                    FaultKind::TurntableTimeout,
                    true,
                    ", re-homing",
                    Recovery::Home,
                ),
            },
            (true, ErrorKind::Protocol) => {
                (FaultKind::TurntableProtocol, true, "", Recovery::Retry)
            }
            // Lost position, never homed, or commands locked out after an alarm (GRBL error:9).
            (true, ErrorKind::NeedsHoming) => {
                let what = if homing {
                    ", homing again"
                } else {
                    ", re-homing"
                };
                (FaultKind::TurntableLost, false, what, Recovery::Home)
            }
            (true, ErrorKind::Disconnected) => {
                let kind = FaultKind::TurntableDisconnect;
                (kind, false, ", reconnecting", Recovery::Reconnect)
            }
            (false, ErrorKind::FrameDropped | ErrorKind::Timeout) => {
                (FaultKind::FrameDropped, true, "", Recovery::Retry)
            }
            (false, ErrorKind::CorruptedFrame) => {
                (FaultKind::FrameCorrupted, true, "", Recovery::Retry)
            }
            (false, ErrorKind::Disconnected) => {
                let kind = FaultKind::CameraDisconnect;
                (kind, true, ", reconnecting", Recovery::Reconnect)
            }
            _ => return Err(e.into()),
        };
        Ok(Noted {
            kind,
            attempt,
            detail: format!("{e}{suffix}"),
            recovery,
        })
    }
}

/// The rig with its retry policy; faults go to `log`.
pub struct Devices<'a> {
    /// The devices.
    pub rig: &'a mut Rig,
    /// Faults met so far.
    pub log: &'a mut Vec<FaultEvent>,
}

impl Devices<'_> {
    /// Records a fault (and logs it as a warning).
    pub fn note(&mut self, kind: FaultKind, attempt: Option<usize>, detail: String) {
        let event = FaultEvent {
            kind,
            attempt: attempt.map(|a| a as u32),
            detail,
        };
        tracing::warn!("{event}");
        self.log.push(event);
    }

    /// Moves the turntable to `angle` degrees, handling timeouts, garbled answers, lost
    /// positions (re-homing) and disconnects (reconnecting); a fault while re-homing or
    /// reconnecting counts as a failed attempt too. A controller that cannot be reopened (the
    /// port is gone) ends the job with the driver's error; the job can be resumed.
    pub fn move_to(&mut self, angle: f64) -> Result<()> {
        self.retry(Step::Move(angle), |rig| {
            rig.turntable.move_to(angle, MOVE_TIMEOUT)?;
            let now = rig.turntable.angle()?;
            if (now - angle).abs() < 1e-3 {
                Ok(Ok(()))
            } else {
                Ok(Err(Noted {
                    kind: FaultKind::TurntablePosition,
                    attempt: false,
                    detail: format!("at {now:.4}° instead of {angle:.4}°, re-homing"),
                    recovery: Recovery::Home,
                }))
            }
        })
    }

    /// Homes the turntable with the retry policy of [`Devices::move_to`].
    pub fn home(&mut self) -> Result<()> {
        self.retry(Step::Home, |rig| {
            rig.turntable.home(MOVE_TIMEOUT)?;
            Ok(Ok(()))
        })
    }

    /// One good frame at `exposure` seconds, handling drops, corruption and disconnects.
    pub fn frame(&mut self, exposure: f64) -> Result<BayerFrame> {
        self.retry(Step::Frame(exposure), |rig| {
            rig.camera.set_exposure(exposure)?;
            let f = rig.camera.capture(FRAME_TIMEOUT)?;
            Ok(f.validate().map(|()| f).map_err(|e| Noted {
                kind: FaultKind::FrameRejected,
                attempt: true,
                detail: e.to_string(),
                recovery: Recovery::Retry,
            }))
        })
    }

    /// The retry policy, one loop for every step: an attempt first does what the previous
    /// fault asked for ([`Recovery`]), then the step; a device error is matched on its
    /// [`ErrorKind`], logged as a [`FaultEvent`] and retried, or (a kind the policy does not
    /// handle) ends the job.
    fn retry<T>(
        &mut self,
        step: Step,
        mut attempt: impl FnMut(&mut Rig) -> Result<Result<T, Noted>, HalError>,
    ) -> Result<T> {
        let mut recovery = Recovery::Retry;
        for n in 1..=MAX_RETRIES {
            let r = match self.recover(step, recovery) {
                // The camera's reconnect is not retried: a camera that cannot be reopened ends
                // the job.
                Err(e) if matches!(step, Step::Frame(_)) => return Err(e.into()),
                r => r.and_then(|()| attempt(&mut *self.rig)),
            };
            let noted = match r {
                Ok(Ok(value)) => return Ok(value),
                Ok(Err(noted)) => noted,
                Err(e) => Noted::of(step, e)?,
            };
            self.note(noted.kind, noted.attempt.then_some(n), noted.detail);
            recovery = noted.recovery;
        }
        Err(AcquireError::RetriesExhausted(match step {
            Step::Move(angle) => {
                format!("turntable did not reach {angle}° after {MAX_RETRIES} attempts")
            }
            Step::Home => format!("turntable did not home after {MAX_RETRIES} attempts"),
            Step::Frame(exposure) => {
                format!("camera gave no good frame at {exposure} s after {MAX_RETRIES} attempts")
            }
        }))
    }

    /// What an attempt does before its step: reconnect (and then re-home) the turntable,
    /// re-home it, or reconnect the camera.
    fn recover(&mut self, step: Step, recovery: Recovery) -> Result<(), HalError> {
        let rig = &mut *self.rig;
        match (step, recovery) {
            (_, Recovery::Retry) | (Step::Home, Recovery::Home) => Ok(()),
            (Step::Frame(_), _) => rig.camera.reconnect(),
            // Homing is the step itself.
            (Step::Home, Recovery::Reconnect) => rig.turntable.reconnect(),
            (Step::Move(_), Recovery::Reconnect) => {
                rig.turntable.reconnect()?;
                rig.turntable.home(MOVE_TIMEOUT)
            }
            (Step::Move(_), Recovery::Home) => rig.turntable.home(MOVE_TIMEOUT),
        }
    }

    /// Checks the lamp after a series: `Ok(false)` when the series must be repeated.
    pub fn lamp_ok(&mut self) -> Result<bool> {
        match self.rig.lamp.state() {
            Ok(LampState::Stable) => Ok(true),
            Ok(LampState::Off) => {
                self.note(
                    FaultKind::LampOff,
                    None,
                    "lamp found off, relighting and repeating the series".into(),
                );
                self.rig.lamp.set_on(true)?;
                self.rig.lamp.wait_stable(LAMP_TIMEOUT)?;
                Ok(false)
            }
            Ok(other) => {
                self.note(FaultKind::LampUnstable, None, format!("{other:?}, waiting"));
                self.rig.lamp.wait_stable(LAMP_TIMEOUT)?;
                Ok(false)
            }
            Err(e) if e.kind() == ErrorKind::LampDropout => {
                self.note(
                    FaultKind::LampDropout,
                    None,
                    format!("{e}, relighting and repeating the series"),
                );
                self.rig.lamp.set_on(true)?;
                self.rig.lamp.wait_stable(LAMP_TIMEOUT)?;
                Ok(false)
            }
            Err(e) if e.kind() == ErrorKind::LampFlicker => {
                self.note(
                    FaultKind::LampFlicker,
                    None,
                    format!("{e}, repeating the series"),
                );
                self.rig.lamp.wait_stable(LAMP_TIMEOUT)?;
                Ok(false)
            }
            Err(e) => Err(e.into()),
        }
    }
}
