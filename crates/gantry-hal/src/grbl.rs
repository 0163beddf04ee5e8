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

use crate::device::{Lamp, LampState, Turntable};
use crate::error::{DeviceKind, HalError, HalResult};
use serde::{Deserialize, Serialize};
use serialport::SerialPort;
use std::io::{ErrorKind, Read, Write};
use std::sync::{Arc, Mutex, MutexGuard};
use std::time::{Duration, Instant};

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

/// Reopens the serial link after a disconnect.
pub type Connector = Box<dyn FnMut() -> HalResult<Box<dyn SerialPort>> + Send>;

/// A GRBL controller on a serial link. Shared by [`GrblTurntable`] and [`GrblLamp`].
pub struct GrblController {
    port: Option<Box<dyn SerialPort>>,
    connector: Option<Connector>,
    config: GrblConfig,
    pending: Vec<u8>,
    banner: String,
}

impl std::fmt::Debug for GrblController {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("GrblController")
            .field("port", &self.config.port)
            .field("banner", &self.banner)
            .finish_non_exhaustive()
    }
}

fn secs(s: f64) -> Duration {
    Duration::from_secs_f64(s.max(0.0))
}

fn open_port(path: &str, baud: u32) -> HalResult<Box<dyn SerialPort>> {
    serialport::new(path, baud)
        .timeout(Duration::from_millis(20))
        .open()
        .map_err(|e| HalError::DeviceAbsent {
            device: DeviceKind::MotionController,
            name: path.to_string(),
            detail: e.to_string(),
        })
}

impl GrblController {
    /// Opens the configured serial port, resets the controller and waits for its banner.
    /// A missing port is [`HalError::DeviceAbsent`] immediately; a port with no GRBL behind it
    /// is [`HalError::DeviceAbsent`] after `banner_timeout_s`.
    pub fn open(config: GrblConfig) -> HalResult<Self> {
        let port = open_port(&config.port, config.baud)?;
        let (path, baud) = (config.port.clone(), config.baud);
        let connector: Connector = Box::new(move || open_port(&path, baud));
        let mut c = Self::from_port(port, Some(connector), config)?;
        if let Err(e) = c.reset() {
            return Err(match e {
                HalError::Timeout { .. } => HalError::DeviceAbsent {
                    device: DeviceKind::MotionController,
                    name: c.config.port.clone(),
                    detail: "port opened but no GRBL banner after reset".into(),
                },
                other => other,
            });
        }
        Ok(c)
    }

    /// Wraps an already open link (e.g. one end of a pseudo-terminal pair). `connector`, if
    /// given, is used by [`GrblController::reconnect`]. Does not reset the controller.
    pub fn from_port(
        mut port: Box<dyn SerialPort>,
        connector: Option<Connector>,
        config: GrblConfig,
    ) -> HalResult<Self> {
        if !"XYZ".contains(config.axis) {
            return Err(HalError::Config(format!(
                "GRBL axis must be X, Y or Z, not '{}'",
                config.axis
            )));
        }
        port.set_timeout(Duration::from_millis(20))
            .map_err(|e| io_err(e.into()))?;
        Ok(Self {
            port: Some(port),
            connector,
            config,
            pending: Vec::new(),
            banner: String::new(),
        })
    }

    /// The configuration.
    pub fn config(&self) -> &GrblConfig {
        &self.config
    }

    /// The start-up banner seen after the last reset (e.g. `Grbl 1.1h ['$' for help]`).
    pub fn banner(&self) -> &str {
        &self.banner
    }

    fn port(&mut self) -> HalResult<&mut Box<dyn SerialPort>> {
        self.port.as_mut().ok_or_else(|| HalError::Disconnected {
            device: DeviceKind::MotionController,
            detail: "link closed; reconnect first".into(),
        })
    }

    fn write_raw(&mut self, bytes: &[u8]) -> HalResult<()> {
        let r = self.port()?.write_all(bytes);
        r.map_err(|e| self.link_error(e))
    }

    fn link_error(&mut self, e: std::io::Error) -> HalError {
        match e.kind() {
            ErrorKind::BrokenPipe
            | ErrorKind::NotConnected
            | ErrorKind::UnexpectedEof
            | ErrorKind::ConnectionReset => {
                self.port = None;
                HalError::Disconnected {
                    device: DeviceKind::MotionController,
                    detail: e.to_string(),
                }
            }
            _ if e.raw_os_error() == Some(5) => {
                // EIO: the other side of a tty went away.
                self.port = None;
                HalError::Disconnected {
                    device: DeviceKind::MotionController,
                    detail: e.to_string(),
                }
            }
            _ => io_err(e),
        }
    }

    /// Reads one line (without the line ending) before `deadline`.
    fn read_line(&mut self, deadline: Instant, operation: &str) -> HalResult<String> {
        loop {
            if let Some(pos) = self.pending.iter().position(|&b| b == b'\n') {
                let line: Vec<u8> = self.pending.drain(..=pos).collect();
                let s = String::from_utf8_lossy(&line).trim().to_string();
                if s.is_empty() {
                    continue;
                }
                tracing::trace!(target: "grbl", "<- {s}");
                return Ok(s);
            }
            if Instant::now() >= deadline {
                return Err(HalError::Timeout {
                    device: DeviceKind::MotionController,
                    operation: operation.to_string(),
                    after: deadline.saturating_duration_since(Instant::now()),
                });
            }
            let mut buf = [0u8; 256];
            let r = self.port()?.read(&mut buf);
            match r {
                Ok(0) => {
                    return Err(self.link_error(std::io::Error::new(
                        ErrorKind::UnexpectedEof,
                        "end of stream",
                    )))
                }
                Ok(n) => self.pending.extend_from_slice(&buf[..n]),
                Err(e) if e.kind() == ErrorKind::TimedOut || e.kind() == ErrorKind::WouldBlock => {}
                Err(e) if e.kind() == ErrorKind::Interrupted => {}
                Err(e) => return Err(self.link_error(e)),
            }
        }
    }

    fn timeout_error(operation: &str, after: Duration) -> HalError {
        HalError::Timeout {
            device: DeviceKind::MotionController,
            operation: operation.to_string(),
            after,
        }
    }

    /// Soft-resets the controller (0x18) and waits for its banner.
    pub fn reset(&mut self) -> HalResult<()> {
        self.pending.clear();
        self.write_raw(&[0x18])?;
        let wait = secs(self.config.banner_timeout_s);
        let deadline = Instant::now() + wait;
        loop {
            let line = self.read_line(deadline, "reset").map_err(|e| match e {
                HalError::Timeout { .. } => Self::timeout_error("reset (banner)", wait),
                other => other,
            })?;
            if let Some(rest) = line.strip_prefix("Grbl ") {
                if !rest.starts_with("1.1") {
                    tracing::warn!("GRBL version '{rest}' is not 1.1");
                }
                self.banner = line;
                return Ok(());
            }
        }
    }

    /// Sends one line command and waits for `ok`. `error:N` becomes [`HalError::GrblError`],
    /// `ALARM:N` an alarm error (see [`GrblController::alarm_error`]).
    pub fn command(&mut self, cmd: &str, timeout: Duration) -> HalResult<()> {
        tracing::trace!(target: "grbl", "-> {cmd}");
        self.write_raw(format!("{cmd}\n").as_bytes())?;
        let deadline = Instant::now() + timeout;
        loop {
            let line = self.read_line(deadline, cmd).map_err(|e| match e {
                HalError::Timeout { .. } => Self::timeout_error(cmd, timeout),
                other => other,
            })?;
            if line == "ok" {
                return Ok(());
            }
            if let Some(code) = line.strip_prefix("error:") {
                let code: u8 = code.trim().parse().unwrap_or(0);
                return Err(HalError::GrblError {
                    code,
                    message: error_message(code).into(),
                    command: cmd.to_string(),
                });
            }
            if let Some(code) = line.strip_prefix("ALARM:") {
                return Err(Self::alarm_error(code.trim().parse().unwrap_or(0)));
            }
            // Status reports, [MSG:...] and banners are not answers to the command.
        }
    }

    /// Maps an alarm code to an error: alarms that lose the machine position (hard limit,
    /// reset in motion, homing failures) become [`HalError::LostPosition`].
    pub fn alarm_error(code: u8) -> HalError {
        match code {
            1 | 3 | 6..=9 => HalError::LostPosition {
                detail: format!("GRBL ALARM:{code}: {}", alarm_message(code)),
            },
            _ => HalError::GrblAlarm {
                code,
                message: alarm_message(code).into(),
            },
        }
    }

    /// Sends `?` and waits for the status report.
    pub fn status(&mut self, timeout: Duration) -> HalResult<GrblStatus> {
        self.write_raw(b"?")?;
        let deadline = Instant::now() + timeout;
        loop {
            let line = self.read_line(deadline, "status").map_err(|e| match e {
                HalError::Timeout { .. } => Self::timeout_error("status query '?'", timeout),
                other => other,
            })?;
            if line.starts_with('<') {
                return parse_status(&line);
            }
            if let Some(code) = line.strip_prefix("ALARM:") {
                return Err(Self::alarm_error(code.trim().parse().unwrap_or(0)));
            }
        }
    }

    /// Polls status until the machine is idle. On timeout a feed hold (`!`) is sent.
    pub fn wait_idle(&mut self, timeout: Duration, operation: &str) -> HalResult<GrblStatus> {
        let start = Instant::now();
        let poll = secs(self.config.poll_interval_s);
        let per_query = secs(self.config.command_timeout_s);
        loop {
            let st = self.status(per_query)?;
            match st.state {
                GrblState::Idle => return Ok(st),
                GrblState::Alarm => {
                    return Err(HalError::LostPosition {
                        detail: format!("controller in alarm state during {operation}"),
                    })
                }
                GrblState::Door => {
                    return Err(HalError::GrblAlarm {
                        code: 0,
                        message: "safety door open".into(),
                    })
                }
                _ => {}
            }
            if start.elapsed() >= timeout {
                let _ = self.write_raw(b"!");
                return Err(HalError::Timeout {
                    device: DeviceKind::Turntable,
                    operation: operation.to_string(),
                    after: timeout,
                });
            }
            std::thread::sleep(poll);
        }
    }

    /// Drops the link, reopens it through the connector and resets the controller.
    pub fn reconnect(&mut self) -> HalResult<()> {
        self.port = None;
        let connector = self
            .connector
            .as_mut()
            .ok_or_else(|| HalError::Disconnected {
                device: DeviceKind::MotionController,
                detail: "no way to reopen this link".into(),
            })?;
        let mut port = connector()?;
        port.set_timeout(Duration::from_millis(20))
            .map_err(|e| io_err(e.into()))?;
        self.port = Some(port);
        self.reset()
    }
}

fn io_err(e: std::io::Error) -> HalError {
    HalError::Io {
        device: DeviceKind::MotionController,
        source: e,
    }
}

/// A GRBL controller shared by the turntable and the lamp.
pub type SharedGrbl = Arc<Mutex<GrblController>>;

fn lock(c: &SharedGrbl) -> HalResult<MutexGuard<'_, GrblController>> {
    c.lock().map_err(|_| HalError::Disconnected {
        device: DeviceKind::MotionController,
        detail: "controller lock poisoned".into(),
    })
}

/// The turntable as a rotary axis of a GRBL controller.
#[derive(Debug)]
pub struct GrblTurntable {
    ctl: SharedGrbl,
    speed: f64,
    home_offset: Option<f64>,
}

impl GrblTurntable {
    /// A turntable on the shared controller. It must be homed before moving.
    pub fn new(ctl: SharedGrbl) -> HalResult<Self> {
        let speed = lock(&ctl)?.config.speed_deg_per_s;
        Ok(Self {
            ctl,
            speed,
            home_offset: None,
        })
    }

    fn axis_index(c: &GrblController) -> usize {
        match c.config.axis {
            'Y' => 1,
            'Z' => 2,
            _ => 0,
        }
    }

    fn read_axis(c: &mut GrblController, st: &GrblStatus) -> HalResult<f64> {
        let i = Self::axis_index(c);
        st.position
            .get(i)
            .copied()
            .ok_or_else(|| HalError::Protocol {
                device: DeviceKind::MotionController,
                detail: format!("status report has no axis {}", c.config.axis),
            })
    }
}

impl Turntable for GrblTurntable {
    fn home(&mut self, timeout: Duration) -> HalResult<()> {
        let ctl = self.ctl.clone();
        let mut c = lock(&ctl)?;
        self.home_offset = None;
        // A move interrupted by a feed hold must be flushed by a soft reset before homing.
        let t = secs(c.config.command_timeout_s);
        match c.status(t) {
            Ok(st) if matches!(st.state, GrblState::Hold | GrblState::Run | GrblState::Jog) => {
                c.reset()?
            }
            Ok(_) | Err(HalError::LostPosition { .. }) => {}
            Err(e) => return Err(e),
        }
        c.command("$H", timeout)?;
        let st = c.wait_idle(timeout, "homing")?;
        self.home_offset = Some(Self::read_axis(&mut c, &st)?);
        Ok(())
    }

    fn move_to(&mut self, angle_deg: f64, timeout: Duration) -> HalResult<()> {
        if !angle_deg.is_finite() {
            return Err(HalError::InvalidArgument(format!("angle {angle_deg}")));
        }
        let offset = self.home_offset.ok_or(HalError::NotHomed)?;
        let ctl = self.ctl.clone();
        let mut c = lock(&ctl)?;
        let axis = c.config.axis;
        let cmd_timeout = secs(c.config.command_timeout_s);
        let cmd = format!(
            "G90 G1 {axis}{:.4} F{:.3}",
            angle_deg + offset,
            self.speed * 60.0
        );
        let r = c
            .command(&cmd, cmd_timeout)
            .and_then(|_| c.wait_idle(timeout, &format!("move to {angle_deg:.3}°")));
        match r {
            Ok(st) => {
                let at = Self::read_axis(&mut c, &st)? - offset;
                if (at - angle_deg).abs() > 1e-3 {
                    self.home_offset = None;
                    return Err(HalError::LostPosition {
                        detail: format!("commanded {angle_deg:.4}°, controller reports {at:.4}°"),
                    });
                }
                Ok(())
            }
            Err(e) => {
                // After a timeout the axis is held somewhere on the way: home again.
                if matches!(
                    e,
                    HalError::LostPosition { .. }
                        | HalError::Disconnected { .. }
                        | HalError::Timeout { .. }
                ) {
                    self.home_offset = None;
                }
                Err(e)
            }
        }
    }

    fn angle(&mut self) -> HalResult<f64> {
        let offset = self.home_offset.ok_or(HalError::NotHomed)?;
        let ctl = self.ctl.clone();
        let mut c = lock(&ctl)?;
        let t = secs(c.config.command_timeout_s);
        let st = c.status(t)?;
        Ok(Self::read_axis(&mut c, &st)? - offset)
    }

    fn speed(&self) -> f64 {
        self.speed
    }

    fn set_speed(&mut self, deg_per_s: f64) -> HalResult<()> {
        if !(deg_per_s.is_finite() && deg_per_s > 0.0) {
            return Err(HalError::InvalidArgument(format!(
                "turntable speed {deg_per_s} deg/s"
            )));
        }
        self.speed = deg_per_s;
        Ok(())
    }

    fn reconnect(&mut self) -> HalResult<()> {
        self.home_offset = None;
        lock(&self.ctl)?.reconnect()
    }
}

/// The lamp on a spindle or coolant output of a GRBL controller. Warm-up is timed on the wall
/// clock; the controller's accessory state is checked on every [`Lamp::state`] call, so a lamp
/// output that dropped is reported as [`HalError::LampDropout`].
#[derive(Debug)]
pub struct GrblLamp {
    ctl: SharedGrbl,
    output: LampOutput,
    warm_up: f64,
    on_since: Option<Instant>,
    epoch: Instant,
}

impl GrblLamp {
    /// A lamp on the shared controller.
    pub fn new(ctl: SharedGrbl) -> HalResult<Self> {
        let (output, warm_up) = {
            let c = lock(&ctl)?;
            (c.config.lamp_output, c.config.lamp_warm_up_s)
        };
        Ok(Self {
            ctl,
            output,
            warm_up,
            on_since: None,
            epoch: Instant::now(),
        })
    }
}

impl Lamp for GrblLamp {
    fn set_on(&mut self, on: bool) -> HalResult<()> {
        let cmd = match (on, self.output) {
            (true, LampOutput::Spindle { s_value }) => format!("M3 S{s_value:.0}"),
            (false, LampOutput::Spindle { .. }) => "M5".into(),
            (true, LampOutput::Flood) => "M8".into(),
            (true, LampOutput::Mist) => "M7".into(),
            (false, _) => "M9".into(),
        };
        let mut c = lock(&self.ctl)?;
        let t = secs(c.config.command_timeout_s);
        c.command(&cmd, t)?;
        if on {
            if self.on_since.is_none() {
                self.on_since = Some(Instant::now());
            }
        } else {
            self.on_since = None;
        }
        Ok(())
    }

    fn state(&mut self) -> HalResult<LampState> {
        let st = {
            let mut c = lock(&self.ctl)?;
            let t = secs(c.config.command_timeout_s);
            c.status(t)?
        };
        let output_on = match self.output {
            LampOutput::Spindle { .. } => st.spindle_on,
            LampOutput::Flood => st.flood_on,
            LampOutput::Mist => st.mist_on,
        };
        match (self.on_since, output_on) {
            (None, _) => Ok(LampState::Off),
            (Some(_), false) => {
                self.on_since = None;
                Err(HalError::LampDropout {
                    at_s: self.epoch.elapsed().as_secs_f64(),
                })
            }
            (Some(t0), true) => {
                let on_for = t0.elapsed().as_secs_f64();
                if on_for >= self.warm_up {
                    Ok(LampState::Stable)
                } else {
                    Ok(LampState::WarmingUp {
                        remaining_s: self.warm_up - on_for,
                    })
                }
            }
        }
    }

    fn warm_up_s(&self) -> f64 {
        self.warm_up
    }

    fn wait_stable(&mut self, timeout: Duration) -> HalResult<()> {
        let start = Instant::now();
        loop {
            match self.state()? {
                LampState::Stable => return Ok(()),
                LampState::Off => {
                    return Err(HalError::LampNotStable {
                        detail: "lamp is off".into(),
                    })
                }
                LampState::WarmingUp { remaining_s } => {
                    let left = timeout.saturating_sub(start.elapsed());
                    if left.is_zero() {
                        return Err(HalError::Timeout {
                            device: DeviceKind::Lamp,
                            operation: "wait for stable output".into(),
                            after: timeout,
                        });
                    }
                    std::thread::sleep(left.min(secs(remaining_s)).min(Duration::from_secs(1)));
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

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

    #[test]
    fn alarms_that_lose_position_map_to_lost_position() {
        assert!(matches!(
            GrblController::alarm_error(1),
            HalError::LostPosition { .. }
        ));
        assert!(matches!(
            GrblController::alarm_error(2),
            HalError::GrblAlarm { code: 2, .. }
        ));
    }

    #[test]
    fn absent_port_fails_fast_naming_it() {
        let t0 = Instant::now();
        let cfg = GrblConfig {
            port: "/dev/does-not-exist-gantry".into(),
            ..Default::default()
        };
        let e = GrblController::open(cfg).unwrap_err();
        assert!(t0.elapsed() < Duration::from_secs(1));
        assert!(matches!(e, HalError::DeviceAbsent { .. }));
        assert!(e.to_string().contains("/dev/does-not-exist-gantry"), "{e}");
    }
}
