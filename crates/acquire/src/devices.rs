//! The retry policy of the devices: a fault a device reports is logged as a [`FaultEvent`],
//! handled (re-home, reconnect, relight, wait) and the step retried; any other error ends the
//! job, which can then be resumed.

use crate::error::{AcquireError, Result};
use gantry_hal::{BayerFrame, HalError, LampState, Rig};
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
        let mut need_home = false;
        let mut need_reconnect = false;
        for attempt in 1..=MAX_RETRIES {
            let r = self.try_move(angle, &mut need_home, &mut need_reconnect);
            match r {
                Ok(now) => {
                    if (now - angle).abs() < 1e-3 {
                        return Ok(());
                    }
                    self.note(
                        FaultKind::TurntablePosition,
                        None,
                        format!("at {now:.4}° instead of {angle:.4}°, re-homing"),
                    );
                    need_home = true;
                }
                Err(e @ HalError::Timeout { .. }) => {
                    // The axis may be held anywhere on the way: home before the next attempt.
                    self.note(
                        FaultKind::TurntableTimeout,
                        Some(attempt),
                        format!("{e}, re-homing"),
                    );
                    need_home = true;
                }
                Err(e @ HalError::Protocol { .. }) => {
                    self.note(FaultKind::TurntableProtocol, Some(attempt), e.to_string());
                }
                // error:9: G-code locked out, the controller is in alarm (it reset itself).
                Err(
                    e @ (HalError::LostPosition { .. }
                    | HalError::NotHomed
                    | HalError::GrblError { code: 9, .. }),
                ) => {
                    self.note(FaultKind::TurntableLost, None, format!("{e}, re-homing"));
                    need_home = true;
                }
                Err(e @ HalError::Disconnected { .. }) => {
                    self.note(
                        FaultKind::TurntableDisconnect,
                        None,
                        format!("{e}, reconnecting"),
                    );
                    need_reconnect = true;
                }
                Err(e) => return Err(e.into()),
            }
        }
        Err(AcquireError::RetriesExhausted(format!(
            "turntable did not reach {angle}° after {MAX_RETRIES} attempts"
        )))
    }

    /// Homes the turntable with the retry policy of [`Devices::move_to`].
    pub fn home(&mut self) -> Result<()> {
        let mut need_reconnect = false;
        for attempt in 1..=MAX_RETRIES {
            let r = if need_reconnect {
                self.rig.turntable.reconnect()
            } else {
                Ok(())
            };
            let r = r.and_then(|_| {
                need_reconnect = false;
                self.rig.turntable.home(MOVE_TIMEOUT)
            });
            match r {
                Ok(()) => return Ok(()),
                Err(e @ HalError::Timeout { .. }) => {
                    self.note(FaultKind::TurntableTimeout, Some(attempt), e.to_string())
                }
                Err(e @ HalError::Protocol { .. }) => {
                    self.note(FaultKind::TurntableProtocol, Some(attempt), e.to_string())
                }
                Err(
                    e @ (HalError::LostPosition { .. }
                    | HalError::NotHomed
                    | HalError::GrblError { code: 9, .. }),
                ) => self.note(FaultKind::TurntableLost, None, format!("{e}, homing again")),
                Err(e @ HalError::Disconnected { .. }) => {
                    self.note(
                        FaultKind::TurntableDisconnect,
                        None,
                        format!("{e}, reconnecting"),
                    );
                    need_reconnect = true;
                }
                Err(e) => return Err(e.into()),
            }
        }
        Err(AcquireError::RetriesExhausted(format!(
            "turntable did not home after {MAX_RETRIES} attempts"
        )))
    }

    /// One attempt of a move: reconnect and re-home first when an earlier attempt asked for
    /// it; returns the angle the turntable reports afterwards.
    fn try_move(
        &mut self,
        angle: f64,
        need_home: &mut bool,
        need_reconnect: &mut bool,
    ) -> Result<f64, HalError> {
        if *need_reconnect {
            self.rig.turntable.reconnect()?;
            *need_reconnect = false;
            *need_home = true;
        }
        if *need_home {
            self.rig.turntable.home(MOVE_TIMEOUT)?;
            *need_home = false;
        }
        self.rig.turntable.move_to(angle, MOVE_TIMEOUT)?;
        self.rig.turntable.angle()
    }

    /// One good frame at `exposure` seconds, handling drops, corruption and disconnects.
    pub fn frame(&mut self, exposure: f64) -> Result<BayerFrame> {
        for attempt in 1..=MAX_RETRIES {
            let r = self
                .rig
                .camera
                .set_exposure(exposure)
                .and_then(|_| self.rig.camera.capture(FRAME_TIMEOUT));
            match r {
                Ok(f) => match f.validate() {
                    Ok(()) => return Ok(f),
                    Err(e) => self.note(FaultKind::FrameRejected, Some(attempt), e.to_string()),
                },
                Err(e @ (HalError::FrameDropped { .. } | HalError::Timeout { .. })) => {
                    self.note(FaultKind::FrameDropped, Some(attempt), e.to_string());
                }
                Err(e @ HalError::CorruptedFrame { .. }) => {
                    self.note(FaultKind::FrameCorrupted, Some(attempt), e.to_string())
                }
                Err(e @ HalError::Disconnected { .. }) => {
                    self.note(
                        FaultKind::CameraDisconnect,
                        Some(attempt),
                        format!("{e}, reconnecting"),
                    );
                    self.rig.camera.reconnect()?;
                }
                Err(e) => return Err(e.into()),
            }
        }
        Err(AcquireError::RetriesExhausted(format!(
            "camera gave no good frame at {exposure} s after {MAX_RETRIES} attempts"
        )))
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
            Err(e @ HalError::LampDropout { .. }) => {
                self.note(
                    FaultKind::LampDropout,
                    None,
                    format!("{e}, relighting and repeating the series"),
                );
                self.rig.lamp.set_on(true)?;
                self.rig.lamp.wait_stable(LAMP_TIMEOUT)?;
                Ok(false)
            }
            Err(e @ HalError::LampFlicker { .. }) => {
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
