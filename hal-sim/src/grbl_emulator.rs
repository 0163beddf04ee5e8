//! A GRBL 1.1 controller emulator on the master side of a pseudo-terminal, so the real serial
//! driver of `gantry-hal` can be tested over an actual tty.

use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use serialport::TTYPort;
use std::collections::VecDeque;
use std::io::{ErrorKind, Read, Write};
use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};
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
    /// Random faults of a hostile link (none by default).
    pub hostile: Option<HostileLink>,
}

/// Probabilities of the faults a hostile link injects, each rolled from a seeded generator.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct HostileLink {
    /// Seed of the fault generator.
    pub seed: u64,
    /// Per burst of replies: line-noise bytes (control and non-ASCII bytes, as a glitch on the
    /// line gives) inserted somewhere.
    pub garbage: f64,
    /// Per burst of replies: sent in two parts with a pause between (a line split across
    /// reads).
    pub split: f64,
    /// Per burst of replies: held back and sent together with the next one (lines merged in
    /// one read).
    pub merge: f64,
    /// Per move: `ALARM:1` (hard limit) half-way through it.
    pub alarm: f64,
    /// Per line command: the controller resets instead of executing it (banner, and the
    /// alarm lock when homing is enabled).
    pub reset: f64,
    /// Per move: the link closes half-way through it.
    pub disconnect: f64,
    /// Per G-code line or status query: never answered (`$` commands such as homing are
    /// always answered).
    pub silence: f64,
}

impl HostileLink {
    /// Every fault at rate `p`.
    pub fn uniform(seed: u64, p: f64) -> Self {
        Self {
            seed,
            garbage: p,
            split: p,
            merge: p,
            alarm: p,
            reset: p,
            disconnect: p,
            silence: p,
        }
    }
}

/// How many faults of each kind a hostile link injected.
#[derive(Debug, Default)]
pub struct InjectedFaults {
    /// Bursts with line noise.
    pub garbage: AtomicUsize,
    /// Bursts split in two.
    pub split: AtomicUsize,
    /// Bursts merged with the next.
    pub merge: AtomicUsize,
    /// Alarms raised during a move.
    pub alarm: AtomicUsize,
    /// Spontaneous resets.
    pub reset: AtomicUsize,
    /// Disconnects in the middle of a move.
    pub disconnect: AtomicUsize,
    /// Commands and queries never answered.
    pub silence: AtomicUsize,
}

impl InjectedFaults {
    /// `(name, count)` of every kind.
    pub fn counts(&self) -> [(&'static str, usize); 7] {
        let g = |a: &AtomicUsize| a.load(Ordering::SeqCst);
        [
            ("garbage", g(&self.garbage)),
            ("split", g(&self.split)),
            ("merge", g(&self.merge)),
            ("alarm", g(&self.alarm)),
            ("reset", g(&self.reset)),
            ("disconnect", g(&self.disconnect)),
            ("silence", g(&self.silence)),
        ]
    }
}

impl Default for GrblEmulatorConfig {
    fn default() -> Self {
        Self {
            time_scale: 1.0,
            homing_enabled: true,
            homing_s: 2.0,
            home_position: [0.0; 3],
            hostile: None,
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
    /// Faults a hostile link injected so far.
    pub injected: InjectedFaults,
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
    disconnect_armed_for_move: bool,
    hang_up: bool,
    line: Vec<u8>,
    rng: ChaCha8Rng,
}

/// A running emulator. Dropping it stops the thread and closes the master side.
///
/// Emulated: the start-up banner and soft reset (0x18), real-time `?` (status report), `!` (feed
/// hold) and `~` (resume); `$H` homing (answers `ok` when the cycle ends), `$X` unlock, `$I`,
/// `$$`; `G0`/`G1` moves with `F` feed (units/min), `G90`/`G91`, `G4` dwell, `M3`/`M4`/`M5`
/// spindle, `M7`/`M8`/`M9` coolant; `error:N` for bad input and for G-code while alarmed; the
/// alarm state after a reset when homing is enabled. Motion runs in wall time, sped up by
/// `time_scale`.
///
/// Faults for tests: a stalled controller that stops answering, a hard-limit `ALARM:1` in the
/// middle of the next move, and a hang-up that closes the link. A hostile link
/// ([`HostileLink`]) injects faults at random from a seeded generator: line noise, replies
/// split in parts or merged with the next one, unexpected alarms and resets, a disconnect in the
/// middle of a move, and commands that are never answered; every injected fault is counted in
/// [`EmulatorFaults::injected`].
///
/// It needs a pseudo-terminal and the `serial` driver of `gantry-hal` to talk to, so its
/// examples are the tests of `hal-sim` (`tests/grbl_pty.rs`) and the hostile-device tests of
/// `acquire`.
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
    pub fn spawn(port: TTYPort, cfg: GrblEmulatorConfig) -> Self {
        Self::spawn_with_faults(port, cfg, Arc::new(EmulatorFaults::default()))
    }

    /// Runs the emulator on `port` with fault switches (and counters) shared with an earlier
    /// emulator, e.g. the controller behind a link that was reopened.
    pub fn spawn_with_faults(
        mut port: TTYPort,
        cfg: GrblEmulatorConfig,
        faults: Arc<EmulatorFaults>,
    ) -> Self {
        let stop = Arc::new(AtomicBool::new(false));
        let (stop2, faults2) = (stop.clone(), faults.clone());
        let thread = std::thread::spawn(move || {
            use serialport::SerialPort;
            let _ = port.set_timeout(Duration::from_millis(5));
            let mut m = Machine::new(cfg);
            let mut out = Vec::new();
            m.banner(&mut out);
            let mut buf = [0u8; 256];
            let mut held = false;
            while !stop2.load(Ordering::SeqCst) {
                if faults2.hang_up.load(Ordering::SeqCst) {
                    break;
                }
                m.update(&faults2, &mut out);
                if m.hang_up {
                    break;
                }
                if !out.is_empty() && m.send(&mut port, &mut out, &faults2, &mut held).is_err() {
                    break;
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
            disconnect_armed_for_move: false,
            hang_up: false,
            line: Vec::new(),
            rng: ChaCha8Rng::seed_from_u64(cfg.hostile.map_or(0, |h| h.seed)),
        }
    }

    /// Rolls a hostile-link fault of probability `pick(link)`.
    fn roll(&mut self, pick: impl Fn(&HostileLink) -> f64) -> bool {
        match self.cfg.hostile {
            Some(h) => {
                let p = pick(&h);
                p > 0.0 && self.rng.gen::<f64>() < p
            }
            None => false,
        }
    }

    /// Writes a burst of replies, with the hostile link's noise, splits and merges.
    fn send(
        &mut self,
        port: &mut TTYPort,
        out: &mut Vec<u8>,
        faults: &EmulatorFaults,
        held: &mut bool,
    ) -> std::io::Result<()> {
        if !*held && self.roll(|h| h.merge) {
            // Sent with whatever comes next (one loop later at the latest).
            faults.injected.merge.fetch_add(1, Ordering::SeqCst);
            *held = true;
            return Ok(());
        }
        *held = false;
        if self.roll(|h| h.garbage) {
            faults.injected.garbage.fetch_add(1, Ordering::SeqCst);
            let n = self.rng.gen_range(1..=4);
            let at = self.rng.gen_range(0..=out.len());
            let noise: Vec<u8> = (0..n)
                .map(|_| match self.rng.gen_range(0..4) {
                    0 => 0x00,
                    1 => 0xff,
                    2 => 0x07,
                    _ => self.rng.gen_range(0x80..=0xfe),
                })
                .collect();
            out.splice(at..at, noise);
        }
        if out.len() > 1 && self.roll(|h| h.split) {
            faults.injected.split.fetch_add(1, Ordering::SeqCst);
            let at = self.rng.gen_range(1..out.len());
            port.write_all(&out[..at])?;
            port.flush()?;
            std::thread::sleep(Duration::from_millis(3));
            port.write_all(&out[at..])?;
        } else {
            port.write_all(out)?;
        }
        out.clear();
        Ok(())
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
                if self.disconnect_armed_for_move && frac >= 0.5 {
                    self.disconnect_armed_for_move = false;
                    faults.injected.disconnect.fetch_add(1, Ordering::SeqCst);
                    self.hang_up = true;
                    return;
                }
                if self.alarm_armed_for_move && frac >= 0.5 {
                    if self.cfg.hostile.is_some() {
                        faults.injected.alarm.fetch_add(1, Ordering::SeqCst);
                    }
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
                        if self.roll(|h| h.alarm) {
                            self.alarm_armed_for_move = true;
                        }
                        if self.roll(|h| h.disconnect) {
                            self.disconnect_armed_for_move = true;
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
            b'?' => {
                if self.roll(|h| h.silence) {
                    faults.injected.silence.fetch_add(1, Ordering::SeqCst);
                } else {
                    out.extend_from_slice(self.status().as_bytes())
                }
            }
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
            0x18 => self.soft_reset(out),
            b'\n' | b'\r' => {
                if self.line.is_empty() && b == b'\r' {
                    return;
                }
                let line = String::from_utf8_lossy(&self.line).trim().to_uppercase();
                self.line.clear();
                // `$` commands are not silenced: homing answers only when the cycle ends, so
                // the driver waits for it as long as for a move (minutes), too long for tests.
                if !line.starts_with('$') && !line.is_empty() && self.roll(|h| h.silence) {
                    faults.injected.silence.fetch_add(1, Ordering::SeqCst);
                } else if self.roll(|h| h.reset) {
                    faults.injected.reset.fetch_add(1, Ordering::SeqCst);
                    self.soft_reset(out);
                } else {
                    self.execute(&line, faults, out);
                }
            }
            _ => {
                if self.line.len() < 256 {
                    self.line.push(b);
                }
            }
        }
    }

    /// Soft reset (0x18, or a spontaneous reset of a hostile controller).
    fn soft_reset(&mut self, out: &mut Vec<u8>) {
        {
            {
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
