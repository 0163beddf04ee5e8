//! The GRBL serial driver (feature `serial`).

use super::*;
use crate::device::{Lamp, LampState, Turntable};
use crate::error::DeviceKind;
use serialport::SerialPort;
use std::io::{ErrorKind, Read, Write};
use std::sync::{Arc, Mutex, MutexGuard};
use std::time::{Duration, Instant};

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
    ///
    /// The port is read once more after the deadline has passed: a reply that arrived while
    /// this thread was not running (a loaded host) is taken, not mistaken for a silent
    /// controller.
    fn read_line(&mut self, deadline: Instant, operation: &str) -> HalResult<String> {
        let mut expired = false;
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
            if expired {
                return Err(HalError::Timeout {
                    device: DeviceKind::MotionController,
                    operation: operation.to_string(),
                    after: deadline.saturating_duration_since(Instant::now()),
                });
            }
            expired = Instant::now() >= deadline;
            let mut buf = [0u8; 256];
            let r = self.port()?.read(&mut buf);
            match r {
                Ok(0) => {
                    return Err(self.link_error(std::io::Error::new(
                        ErrorKind::UnexpectedEof,
                        "end of stream",
                    )))
                }
                Ok(n) => {
                    self.pending.extend_from_slice(&buf[..n]);
                    if self.pending.len() > 4 * MAX_LINE && !self.pending.contains(&b'\n') {
                        // A babbling link: nothing GRBL sends is this long without a line end.
                        tracing::debug!(target: "grbl", bytes = self.pending.len(), "dropping line noise");
                        self.pending.clear();
                    }
                }
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
            if let Response::Banner(banner) = Response::classify(&line) {
                let rest = &banner["Grbl ".len()..];
                if !rest.starts_with("1.1") {
                    tracing::warn!("GRBL version '{rest}' is not 1.1");
                }
                self.banner = banner;
                // A controller that was just opened may greet twice (on open and after the
                // reset): take what follows the banner within a short quiet time, so that a
                // second greeting is not mistaken later for a spontaneous reset.
                loop {
                    match self.read_line(Instant::now() + Duration::from_millis(50), "reset") {
                        Ok(line) => {
                            if let Response::Banner(b) = Response::classify(&line) {
                                self.banner = b;
                            }
                        }
                        Err(HalError::Timeout { .. }) => return Ok(()),
                        Err(e) => return Err(e),
                    }
                }
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
            match Response::classify(&line) {
                Response::Ok => return Ok(()),
                Response::Error(code) => {
                    return Err(HalError::GrblError {
                        code,
                        message: error_message(code).into(),
                        command: cmd.to_string(),
                    })
                }
                Response::Alarm(code) => return Err(Self::alarm_error(code)),
                Response::Banner(b) => return Err(Self::reset_error(&b, cmd)),
                // Status reports, [MSG:...] and noise are not answers to the command.
                Response::Status(_) | Response::Message(_) | Response::Other(_) => {}
            }
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
            match Response::classify(&line) {
                Response::Status(report) => match parse_status(&report) {
                    Ok(st) => return Ok(st),
                    Err(e) => {
                        // A report garbled on the line: ask again (until the deadline).
                        tracing::debug!(target: "grbl", "{e}; asking again");
                        self.write_raw(b"?")?;
                    }
                },
                Response::Alarm(code) => return Err(Self::alarm_error(code)),
                Response::Banner(b) => return Err(Self::reset_error(&b, "status query '?'")),
                Response::Ok | Response::Error(_) | Response::Message(_) | Response::Other(_) => {}
            }
        }
    }

    /// The error of a start-up banner seen while waiting for `operation`: the controller reset
    /// itself (power glitch, watchdog), which loses the machine position.
    fn reset_error(banner: &str, operation: &str) -> HalError {
        HalError::LostPosition {
            detail: format!("controller reset ('{banner}') while waiting for {operation}"),
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
    fn a_reply_waiting_when_the_deadline_has_passed_is_taken() {
        use std::io::Write;
        // The reply is in the link before the command's deadline is checked, as when the
        // driver's thread was descheduled for longer than the timeout on a loaded host.
        let (mut controller_end, driver_end) = serialport::TTYPort::pair().unwrap();
        let mut c =
            GrblController::from_port(Box::new(driver_end), None, GrblConfig::default()).unwrap();
        controller_end.write_all(b"ok\r\n").unwrap();
        controller_end.flush().unwrap();
        std::thread::sleep(Duration::from_millis(20));
        c.command("G4 P0", Duration::ZERO).unwrap();
        // With nothing in the link it is still a timeout.
        let e = c.command("G4 P0", Duration::ZERO).unwrap_err();
        assert!(matches!(e, HalError::Timeout { .. }), "{e}");
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
