//! Turntable and lamp on a GRBL 1.1 motion controller over a serial port.
//!
//! The turntable is one rotary axis of the controller (configured in GRBL with steps per degree,
//! so positions and feed rates are in degrees and degrees per minute). The lamp hangs on the
//! spindle-enable output (`M3 S…`/`M5`) or on a coolant output (`M8`/`M7`/`M9`).
//!
//! Protocol handled: line commands answered by `ok` or `error:N`; asynchronous `ALARM:N`;
//! real-time `?` status reports `<State|MPos:…|FS:…|A:…>` (also `WPos`); `[MSG:…]` lines;
//! soft reset (0x18) and the `Grbl 1.1x ['$' for help]` banner; homing `$H`; unlock `$X`;
//! feed hold `!`. Every wait has a deadline; a missing port fails at once with
//! [`HalError::DeviceAbsent`], a silent one with [`HalError::Timeout`].
//!
//! The configuration and the protocol (status reports, error and alarm codes) are always
//! available; the serial driver (`GrblController`, `GrblTurntable`, `GrblLamp`) needs the
//! feature `serial`, which pulls the `serialport` crate.

use crate::error::{DeviceKind, HalError, HalResult};
use serde::{Deserialize, Serialize};

/// Settings of a GRBL-driven turntable and lamp.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct GrblConfig {
    /// Serial device path, e.g. `/dev/ttyUSB0`.
    pub port: String,
    /// Baud rate (GRBL 1.1 default 115200).
    pub baud: u32,
    /// Axis letter the turntable is wired to (`X`, `Y` or `Z`).
    pub axis: char,
    /// Rotation speed, degrees per second.
    pub speed_deg_per_s: f64,
    /// How long to wait for `ok` to an ordinary command, seconds.
    pub command_timeout_s: f64,
    /// How long to wait for the start-up banner after a reset, seconds.
    pub banner_timeout_s: f64,
    /// Interval between `?` status polls while waiting for motion, seconds.
    pub poll_interval_s: f64,
    /// Which output switches the lamp.
    pub lamp_output: LampOutput,
    /// Lamp warm-up time after switching on, seconds.
    pub lamp_warm_up_s: f64,
}

impl Default for GrblConfig {
    fn default() -> Self {
        Self {
            port: "/dev/ttyUSB0".into(),
            baud: 115_200,
            axis: 'X',
            speed_deg_per_s: 10.0,
            command_timeout_s: 2.0,
            banner_timeout_s: 3.0,
            poll_interval_s: 0.05,
            lamp_output: LampOutput::Spindle { s_value: 1000.0 },
            lamp_warm_up_s: 600.0,
        }
    }
}

/// Controller output that powers the lamp.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case", tag = "kind")]
pub enum LampOutput {
    /// Spindle enable (`M3 S<s_value>` on, `M5` off).
    Spindle {
        /// Spindle speed word sent with `M3`.
        s_value: f64,
    },
    /// Flood coolant (`M8` on, `M9` off).
    Flood,
    /// Mist coolant (`M7` on, `M9` off).
    Mist,
}

/// Machine state of a status report.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum GrblState {
    /// Ready.
    Idle,
    /// Executing motion.
    Run,
    /// Feed hold.
    Hold,
    /// Jogging.
    Jog,
    /// Locked by an alarm.
    Alarm,
    /// Safety door open.
    Door,
    /// Check mode.
    Check,
    /// Homing cycle running.
    Home,
    /// Sleeping.
    Sleep,
}

/// One parsed `<…>` status report.
#[derive(Debug, Clone, PartialEq)]
pub struct GrblStatus {
    /// Machine state.
    pub state: GrblState,
    /// Axis positions (X, Y, Z, …) from `MPos` or `WPos`.
    pub position: Vec<f64>,
    /// Whether `position` is a work position (`WPos`).
    pub is_work_position: bool,
    /// Spindle running (accessory `S` or `C`).
    pub spindle_on: bool,
    /// Flood coolant on (accessory `F`).
    pub flood_on: bool,
    /// Mist coolant on (accessory `M`).
    pub mist_on: bool,
}

/// One line a GRBL 1.1 controller sent, classified. Line noise (control characters other than
/// tab, and non-ASCII bytes, which a GRBL controller never sends) is removed first, so that a
/// glitch on the serial line does not hide an `ok` or an `ALARM:N`.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Response {
    /// `ok`: the command was accepted.
    Ok,
    /// `error:N` (0 when the code is missing or not a number).
    Error(u8),
    /// `ALARM:N` (0 when the code is missing or not a number).
    Alarm(u8),
    /// A `<…>` status report (parse it with [`parse_status`]).
    Status(String),
    /// The start-up banner `Grbl 1.1x ['$' for help]`: the controller has just reset.
    Banner(String),
    /// A `[…]` message, e.g. `[MSG:'$H'|'$X' to unlock]`.
    Message(String),
    /// Anything else (echo, settings, noise).
    Other(String),
}

/// Longest line a driver keeps; GRBL's own lines are below 128 bytes, so anything longer is
/// noise and is cut (keeps a babbling port from growing the driver's buffer without bound).
pub const MAX_LINE: usize = 256;

impl Response {
    /// Classifies one received line (with or without its line ending).
    pub fn classify(line: &str) -> Response {
        let clean: String = line
            .chars()
            .filter(|c| c.is_ascii_graphic() || *c == ' ')
            .take(MAX_LINE)
            .collect();
        let clean = clean.trim();
        let code = |s: &str| s.trim().parse::<u8>().unwrap_or(0);
        if clean == "ok" {
            Response::Ok
        } else if let Some(c) = clean.strip_prefix("error:") {
            Response::Error(code(c))
        } else if let Some(c) = clean.strip_prefix("ALARM:") {
            Response::Alarm(code(c))
        } else if clean.starts_with('<') && clean.ends_with('>') {
            Response::Status(clean.to_string())
        } else if clean.starts_with("Grbl ") {
            Response::Banner(clean.to_string())
        } else if clean.starts_with('[') {
            Response::Message(clean.to_string())
        } else {
            Response::Other(clean.to_string())
        }
    }
}

/// Parses a GRBL 1.1 status report such as `<Idle|MPos:12.500,0.000,0.000|FS:0,0|A:SF>`.
pub fn parse_status(line: &str) -> HalResult<GrblStatus> {
    let bad = || HalError::Protocol {
        device: DeviceKind::MotionController,
        detail: format!("malformed status report '{line}'"),
    };
    let inner = line
        .trim()
        .strip_prefix('<')
        .and_then(|s| s.strip_suffix('>'))
        .ok_or_else(bad)?;
    let mut fields = inner.split('|');
    let state_field = fields.next().ok_or_else(bad)?;
    let state = match state_field.split(':').next().unwrap_or("") {
        "Idle" => GrblState::Idle,
        "Run" => GrblState::Run,
        "Hold" => GrblState::Hold,
        "Jog" => GrblState::Jog,
        "Alarm" => GrblState::Alarm,
        "Door" => GrblState::Door,
        "Check" => GrblState::Check,
        "Home" => GrblState::Home,
        "Sleep" => GrblState::Sleep,
        _ => return Err(bad()),
    };
    let mut status = GrblStatus {
        state,
        position: Vec::new(),
        is_work_position: false,
        spindle_on: false,
        flood_on: false,
        mist_on: false,
    };
    let mut have_pos = false;
    for f in fields {
        let (key, value) = f.split_once(':').ok_or_else(bad)?;
        match key {
            "MPos" | "WPos" => {
                status.position = value
                    .split(',')
                    .map(|v| v.trim().parse::<f64>().map_err(|_| bad()))
                    .collect::<HalResult<_>>()?;
                if status.position.iter().any(|p| !p.is_finite()) {
                    return Err(bad());
                }
                status.is_work_position = key == "WPos";
                have_pos = true;
            }
            "A" => {
                status.spindle_on = value.contains('S') || value.contains('C');
                status.flood_on = value.contains('F');
                status.mist_on = value.contains('M');
            }
            _ => {}
        }
    }
    if !have_pos {
        return Err(bad());
    }
    Ok(status)
}

/// The [`ErrorKind`](crate::ErrorKind) of a GRBL 1.1 `error:N`: `error:9` (G-code locked out
/// during an alarm, i.e. after the controller reset or lost its position) needs homing; every
/// other code is a rejected command.
pub fn error_kind(code: u8) -> crate::ErrorKind {
    match code {
        9 => crate::ErrorKind::NeedsHoming,
        _ => crate::ErrorKind::Rejected,
    }
}

/// Meaning of a GRBL 1.1 `error:N` code.
pub fn error_message(code: u8) -> &'static str {
    match code {
        1 => "G-code words consist of a letter and a value; letter was not found",
        2 => "numeric value format is not valid or missing an expected value",
        3 => "Grbl '$' system command was not recognized or supported",
        4 => "negative value received for an expected positive value",
        5 => "homing cycle is not enabled via settings",
        8 => "Grbl '$' command cannot be used unless Grbl is IDLE",
        9 => "G-code locked out during alarm or jog state",
        15 => "jog target exceeds machine travel",
        20 => "unsupported or invalid g-code command found in block",
        22 => "feed rate has not yet been set or is undefined",
        24 => "two G-code commands that both require the use of the XYZ axis words were detected",
        _ => "see the GRBL 1.1 error code table",
    }
}

/// Meaning of a GRBL 1.1 `ALARM:N` code.
pub fn alarm_message(code: u8) -> &'static str {
    match code {
        1 => "hard limit triggered; machine position is likely lost",
        2 => "soft limit: motion target exceeds machine travel",
        3 => "reset while in motion; position is likely lost",
        4 => "probe fail: probe not in expected initial state",
        5 => "probe fail: probe did not contact the workpiece",
        6 => "homing fail: reset during active homing cycle",
        7 => "homing fail: safety door opened during homing",
        8 => "homing fail: could not clear limit switch (pull-off)",
        9 => "homing fail: could not find limit switch",
        _ => "unknown alarm",
    }
}

#[cfg(feature = "serial")]
mod driver;
#[cfg(feature = "serial")]
pub use driver::{Connector, GrblController, GrblLamp, GrblTurntable, SharedGrbl};

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn responses_are_classified_through_line_noise() {
        assert_eq!(Response::classify("o\u{0}k\r"), Response::Ok);
        assert_eq!(Response::classify("\u{ff}ALARM:1"), Response::Alarm(1));
        assert_eq!(Response::classify("error:\u{7}9"), Response::Error(9));
        assert_eq!(Response::classify("error:300"), Response::Error(0));
        assert!(matches!(
            Response::classify("Grbl 1.1h ['$' for help]"),
            Response::Banner(_)
        ));
        let noisy = "<Idle|MPos:1.000,\u{80}0.000,0.000|FS:0,0>";
        let Response::Status(report) = Response::classify(noisy) else {
            panic!("not a status report");
        };
        assert_eq!(parse_status(&report).unwrap().position, vec![1.0, 0.0, 0.0]);
        // Babble is cut to MAX_LINE characters.
        let Response::Other(text) = Response::classify(&"x".repeat(10_000)) else {
            panic!("babble is not a response");
        };
        assert_eq!(text.len(), MAX_LINE);
    }

    #[test]
    fn parses_status_reports() {
        let s = parse_status("<Idle|MPos:12.500,0.000,-1.250|FS:0,0|A:SF>").unwrap();
        assert_eq!(s.state, GrblState::Idle);
        assert_eq!(s.position, vec![12.5, 0.0, -1.25]);
        assert!(s.spindle_on && s.flood_on && !s.mist_on && !s.is_work_position);
        let s = parse_status("<Run|WPos:1.000,2.000,3.000|Bf:15,128|FS:500,0>").unwrap();
        assert_eq!(s.state, GrblState::Run);
        assert!(s.is_work_position && !s.spindle_on);
        let s = parse_status("<Hold:0|MPos:0.000,0.000,0.000|FS:0,0>").unwrap();
        assert_eq!(s.state, GrblState::Hold);
    }

    #[test]
    fn rejects_malformed_status() {
        for bad in [
            "Idle|MPos:1,2,3",
            "<Idle|FS:0,0>",
            "<Dancing|MPos:0,0,0>",
            "<Idle|MPos:1,x,3>",
            "<Idle|MPos:NaN,0,0>",
            "<>",
        ] {
            assert!(
                matches!(parse_status(bad), Err(HalError::Protocol { .. })),
                "{bad}"
            );
        }
    }
}
