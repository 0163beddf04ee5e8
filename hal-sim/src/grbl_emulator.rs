//! A GRBL 1.1 controller emulator on the master side of a pseudo-terminal, so the real serial
//! driver of `gantry-hal` can be tested over an actual tty.
//!
//! Emulated: the start-up banner and soft reset (0x18), real-time `?` (status report), `!` (feed
//! hold) and `~` (resume); `$H` homing (answers `ok` when the cycle ends), `$X` unlock, `$I`,
//! `$$`; `G0`/`G1` moves with `F` feed (units/min), `G90`/`G91`, `G4` dwell, `M3`/`M4`/`M5`
//! spindle, `M7`/`M8`/`M9` coolant; `error:N` for bad input and for G-code while alarmed; the
//! alarm state after a reset when homing is enabled. Motion runs in wall time, sped up by
//! `time_scale`.
//!
//! Faults for tests: a stalled controller that stops answering, a hard-limit `ALARM:1` in the
//! middle of the next move, and a hang-up that closes the link.

use serialport::TTYPort;
use std::collections::VecDeque;
use std::io::{ErrorKind, Read, Write};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

/// Emulator settings.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct GrblEmulatorConfig {
    /// Emulated seconds per wall-clock second for motion and dwell.
    pub time_scale: f64,
    /// Whether homing is enabled (`$22=1`): the controller then starts locked in alarm.
    pub homing_enabled: bool,
    /// Duration of a homing cycle in emulated seconds.
    pub homing_s: f64,
    /// Machine position after homing (X, Y, Z).
    pub home_position: [f64; 3],
}

impl Default for GrblEmulatorConfig {
    fn default() -> Self {
        Self {
            time_scale: 1.0,
            homing_enabled: true,
            homing_s: 2.0,
            home_position: [0.0; 3],
        }
    }
}

/// Switches for injected faults, shared with the emulator thread.
#[derive(Debug, Default)]
pub struct EmulatorFaults {
    /// Stop answering anything (as a hung controller would).
    pub stall: AtomicBool,
    /// Raise `ALARM:1` (hard limit) half-way through the next move.
    pub alarm_on_next_move: AtomicBool,
    /// Close the link.
    pub hang_up: AtomicBool,
    /// Drop the spindle and coolant outputs (a tripped lamp supply).
    pub drop_outputs: AtomicBool,
}

#[derive(Debug, Clone, Copy, PartialEq)]
enum State {
    Idle,
    Run,
    Hold,
    Home,
    Alarm,
}

#[derive(Debug, Clone, Copy)]
enum Block {
    Move { target: [f64; 3], feed: f64 },
    Dwell { seconds: f64 },
}

struct Machine {
    cfg: GrblEmulatorConfig,
    state: State,
    pos: [f64; 3],
    absolute: bool,
    feed: Option<f64>,
    spindle: Option<f64>,
    flood: bool,
    mist: bool,
    queue: VecDeque<Block>,
    active: Option<(Block, [f64; 3], Instant, f64)>,
    home_started: Option<Instant>,
    alarm_armed_for_move: bool,
    line: Vec<u8>,
}

/// A running emulator. Dropping it stops the thread and closes the master side.
pub struct GrblEmulator {
    stop: Arc<AtomicBool>,
    faults: Arc<EmulatorFaults>,
    thread: Option<JoinHandle<()>>,
}

impl std::fmt::Debug for GrblEmulator {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("GrblEmulator").finish_non_exhaustive()
    }
}

impl GrblEmulator {
    /// Creates a pseudo-terminal pair, runs the emulator on the master side and returns the
    /// slave side for the driver.
    pub fn spawn_pty(cfg: GrblEmulatorConfig) -> Result<(Self, TTYPort), crate::SimError> {
        let (master, slave) = TTYPort::pair()
            .map_err(|e| crate::SimError::Io(std::io::Error::other(format!("pty pair: {e}"))))?;
        Ok((Self::spawn(master, cfg), slave))
    }

    /// Runs the emulator on `port` in a background thread.
    pub fn spawn(mut port: TTYPort, cfg: GrblEmulatorConfig) -> Self {
        let stop = Arc::new(AtomicBool::new(false));
        let faults = Arc::new(EmulatorFaults::default());
        let (stop2, faults2) = (stop.clone(), faults.clone());
        let thread = std::thread::spawn(move || {
            use serialport::SerialPort;
            let _ = port.set_timeout(Duration::from_millis(5));
            let mut m = Machine::new(cfg);
            let mut out = Vec::new();
            m.banner(&mut out);
            let mut buf = [0u8; 256];
            while !stop2.load(Ordering::SeqCst) {
                if faults2.hang_up.load(Ordering::SeqCst) {
                    break;
                }
                m.update(&faults2, &mut out);
                if !out.is_empty() {
                    if port.write_all(&out).is_err() {
                        break;
                    }
                    out.clear();
                }
                match port.read(&mut buf) {
                    Ok(0) => break,
                    Ok(n) => {
                        if faults2.stall.load(Ordering::SeqCst) {
                            continue;
                        }
                        for &b in &buf[..n] {
                            m.byte(b, &faults2, &mut out);
                        }
                    }
                    Err(e)
                        if e.kind() == ErrorKind::TimedOut || e.kind() == ErrorKind::WouldBlock => {
                    }
                    Err(e) if e.kind() == ErrorKind::Interrupted => {}
                    Err(_) => break,
                }
            }
        });
        Self {
            stop,
            faults,
            thread: Some(thread),
        }
    }

    /// Fault switches of this emulator.
    pub fn faults(&self) -> Arc<EmulatorFaults> {
        self.faults.clone()
    }
}

impl Drop for GrblEmulator {
    fn drop(&mut self) {
        self.stop.store(true, Ordering::SeqCst);
        if let Some(t) = self.thread.take() {
            let _ = t.join();
        }
    }
}

fn fmt3(p: [f64; 3]) -> String {
    format!("{:.3},{:.3},{:.3}", p[0], p[1], p[2])
}

impl Machine {
    fn new(cfg: GrblEmulatorConfig) -> Self {
        Self {
            cfg,
            state: if cfg.homing_enabled {
                State::Alarm
            } else {
                State::Idle
            },
            pos: [0.0; 3],
            absolute: true,
            feed: None,
            spindle: None,
            flood: false,
            mist: false,
            queue: VecDeque::new(),
            active: None,
            home_started: None,
            alarm_armed_for_move: false,
            line: Vec::new(),
        }
    }

    fn banner(&mut self, out: &mut Vec<u8>) {
        out.extend_from_slice(b"\r\nGrbl 1.1h ['$' for help]\r\n");
        if self.cfg.homing_enabled && self.state == State::Alarm {
            out.extend_from_slice(b"[MSG:'$H'|'$X' to unlock]\r\n");
        }
    }

    fn emulated_elapsed(&self, since: Instant) -> f64 {
        since.elapsed().as_secs_f64() * self.cfg.time_scale
    }

    fn update(&mut self, faults: &EmulatorFaults, out: &mut Vec<u8>) {
        if faults.drop_outputs.load(Ordering::SeqCst) {
            self.spindle = None;
            self.flood = false;
            self.mist = false;
        }
        if let Some(t0) = self.home_started {
            if self.emulated_elapsed(t0) >= self.cfg.homing_s {
                self.home_started = None;
                self.pos = self.cfg.home_position;
                self.state = State::Idle;
                out.extend_from_slice(b"ok\r\n");
            }
            return;
        }
        if self.state == State::Hold || self.state == State::Alarm {
            return;
        }
        if let Some((block, from, t0, duration)) = self.active {
            let frac = if duration > 0.0 {
                (self.emulated_elapsed(t0) / duration).min(1.0)
            } else {
                1.0
            };
            if let Block::Move { target, .. } = block {
                for k in 0..3 {
                    self.pos[k] = from[k] + (target[k] - from[k]) * frac;
                }
                if self.alarm_armed_for_move && frac >= 0.5 {
                    self.alarm_armed_for_move = false;
                    self.active = None;
                    self.queue.clear();
                    self.state = State::Alarm;
                    out.extend_from_slice(b"ALARM:1\r\n");
                    return;
                }
            }
            if frac >= 1.0 {
                self.active = None;
            }
        }
        if self.active.is_none() {
            if let Some(block) = self.queue.pop_front() {
                let duration = match block {
                    Block::Move { target, feed } => {
                        let d = (0..3)
                            .map(|k| (target[k] - self.pos[k]).powi(2))
                            .sum::<f64>()
                            .sqrt();
                        if faults.alarm_on_next_move.swap(false, Ordering::SeqCst) {
                            self.alarm_armed_for_move = true;
                        }
                        d / (feed / 60.0)
                    }
                    Block::Dwell { seconds } => seconds,
                };
                self.active = Some((block, self.pos, Instant::now(), duration));
                self.state = State::Run;
            } else if self.state == State::Run {
                self.state = State::Idle;
            }
        }
    }

    fn status(&self) -> String {
        let st = match self.state {
            State::Idle => "Idle",
            State::Run => "Run",
            State::Hold => "Hold:0",
            State::Home => "Home",
            State::Alarm => "Alarm",
        };
        let feed = self.feed.unwrap_or(0.0);
        let s = self.spindle.unwrap_or(0.0);
        let mut acc = String::new();
        if self.spindle.is_some() {
            acc.push('S');
        }
        if self.flood {
            acc.push('F');
        }
        if self.mist {
            acc.push('M');
        }
        let mut line = format!("<{st}|MPos:{}|FS:{feed:.0},{s:.0}", fmt3(self.pos));
        if !acc.is_empty() {
            line.push_str("|A:");
            line.push_str(&acc);
        }
        line.push_str(">\r\n");
        line
    }

    fn byte(&mut self, b: u8, faults: &EmulatorFaults, out: &mut Vec<u8>) {
        match b {
            b'?' => out.extend_from_slice(self.status().as_bytes()),
            b'!' => {
                if self.state == State::Run {
                    self.state = State::Hold;
                }
            }
            b'~' => {
                if self.state == State::Hold {
                    self.state = State::Run;
                }
            }
            0x18 => {
                let was_moving = self.active.is_some() || self.home_started.is_some();
                self.queue.clear();
                self.active = None;
                self.home_started = None;
                self.line.clear();
                self.spindle = None;
                self.flood = false;
                self.mist = false;
                if was_moving {
                    out.extend_from_slice(b"ALARM:3\r\n");
                    self.state = State::Alarm;
                } else if self.cfg.homing_enabled {
                    self.state = State::Alarm;
                } else {
                    self.state = State::Idle;
                }
                self.banner(out);
            }
            b'\n' | b'\r' => {
                if self.line.is_empty() && b == b'\r' {
                    return;
                }
                let line = String::from_utf8_lossy(&self.line).trim().to_uppercase();
                self.line.clear();
                self.execute(&line, faults, out);
            }
            _ => {
                if self.line.len() < 256 {
                    self.line.push(b);
                }
            }
        }
    }

    fn execute(&mut self, line: &str, _faults: &EmulatorFaults, out: &mut Vec<u8>) {
        let reply = |out: &mut Vec<u8>, s: &str| {
            out.extend_from_slice(s.as_bytes());
            out.extend_from_slice(b"\r\n");
        };
        if line.is_empty() {
            return reply(out, "ok");
        }
        if let Some(cmd) = line.strip_prefix('$') {
            return match cmd {
                "H" => {
                    if !self.cfg.homing_enabled {
                        reply(out, "error:5")
                    } else if self.active.is_some() {
                        reply(out, "error:8")
                    } else {
                        self.state = State::Home;
                        self.home_started = Some(Instant::now());
                    }
                }
                "X" => {
                    if self.state == State::Alarm {
                        self.state = State::Idle;
                        reply(out, "[MSG:Caution: Unlocked]");
                    }
                    reply(out, "ok")
                }
                "I" => {
                    reply(out, "[VER:1.1h.20190830:]");
                    reply(out, "[OPT:V,15,128]");
                    reply(out, "ok")
                }
                "$" => {
                    reply(out, "$22=1");
                    reply(out, "$100=200.000");
                    reply(out, "$110=3600.000");
                    reply(out, "ok")
                }
                _ => reply(out, "error:3"),
            };
        }
        if self.state == State::Alarm || self.state == State::Home {
            return reply(out, "error:9");
        }
        match self.parse_gcode(line) {
            Ok(blocks) => {
                self.queue.extend(blocks);
                reply(out, "ok")
            }
            Err(code) => reply(out, &format!("error:{code}")),
        }
    }

    fn parse_gcode(&mut self, line: &str) -> Result<Vec<Block>, u8> {
        let bytes: Vec<char> = line.chars().filter(|c| !c.is_whitespace()).collect();
        let mut words = Vec::new();
        let mut i = 0;
        while i < bytes.len() {
            let letter = bytes[i];
            if !letter.is_ascii_alphabetic() {
                return Err(1);
            }
            i += 1;
            let start = i;
            while i < bytes.len()
                && (bytes[i].is_ascii_digit()
                    || bytes[i] == '.'
                    || bytes[i] == '-'
                    || bytes[i] == '+')
            {
                i += 1;
            }
            let num: String = bytes[start..i].iter().collect();
            let value: f64 = num.parse().map_err(|_| 2u8)?;
            words.push((letter, value));
        }
        let mut motion: Option<u32> = None;
        let mut axes: [Option<f64>; 3] = [None; 3];
        let mut feed = None;
        let mut s = None;
        let mut p = None;
        let mut dwell = false;
        let mut spindle_cmd = None;
        let mut coolant_cmd = None;
        let mut absolute = self.absolute;
        for (l, v) in words {
            match l {
                'G' => match v as u32 {
                    0 | 1 => motion = Some(v as u32),
                    4 => dwell = true,
                    90 => absolute = true,
                    91 => absolute = false,
                    20 | 21 | 17 | 94 => {}
                    _ => return Err(20),
                },
                'M' => match v as u32 {
                    3..=5 => spindle_cmd = Some(v as u32),
                    7..=9 => coolant_cmd = Some(v as u32),
                    _ => return Err(20),
                },
                'X' => axes[0] = Some(v),
                'Y' => axes[1] = Some(v),
                'Z' => axes[2] = Some(v),
                'F' => {
                    if v <= 0.0 {
                        return Err(4);
                    }
                    feed = Some(v)
                }
                'S' => s = Some(v),
                'P' => p = Some(v),
                _ => return Err(20),
            }
        }
        self.absolute = absolute;
        if let Some(f) = feed {
            self.feed = Some(f);
        }
        match spindle_cmd {
            Some(3) | Some(4) => self.spindle = Some(s.or(self.spindle).unwrap_or(0.0)),
            Some(5) => self.spindle = None,
            _ => {}
        }
        match coolant_cmd {
            Some(7) => self.mist = true,
            Some(8) => self.flood = true,
            Some(9) => {
                self.mist = false;
                self.flood = false;
            }
            _ => {}
        }
        let mut blocks = Vec::new();
        if dwell {
            blocks.push(Block::Dwell {
                seconds: p.ok_or(2u8)?.max(0.0),
            });
        }
        if axes.iter().any(|a| a.is_some()) {
            let base = self
                .queue
                .iter()
                .rev()
                .find_map(|b| match b {
                    Block::Move { target, .. } => Some(*target),
                    _ => None,
                })
                .or(self.active.and_then(|(b, ..)| match b {
                    Block::Move { target, .. } => Some(target),
                    _ => None,
                }))
                .unwrap_or(self.pos);
            let mut target = base;
            for k in 0..3 {
                if let Some(v) = axes[k] {
                    target[k] = if absolute { v } else { base[k] + v };
                }
            }
            let rate = match motion {
                Some(0) => 3600.0,
                Some(1) => self.feed.ok_or(22u8)?,
                _ => return Err(20),
            };
            blocks.push(Block::Move { target, feed: rate });
        }
        Ok(blocks)
    }
}
