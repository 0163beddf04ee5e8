//! Hostile devices at reduced size: the turntable is the real GRBL driver talking over a
//! pseudo-terminal to the GRBL emulator, which injects line noise, split and merged lines,
//! unexpected alarms and resets, disconnects in the middle of a move (reconnected through a new
//! pseudo-terminal) and commands never answered; the simulated camera drops, corrupts and loses
//! frames and the simulated lamp flickers and drops out. At 5 % of each the job completes every
//! position and the report lists every fault with how it was handled. A port that vanishes for
//! good stops the job with an error naming it, and the job resumes once the port is back.

use acquire::{
    AcquireError, CalibrationSource, FaultKind, JobSpec, Outcome, RunOptions, SimSetup,
    SimulatedRig, Station,
};
use gantry_hal::grbl::{GrblConfig, GrblController, GrblTurntable};
use gantry_hal::{DeviceKind, HalError, HalResult, Turntable};
use hal_sim::{EmulatorFaults, GrblEmulator, GrblEmulatorConfig, HostileLink};
use std::collections::BTreeMap;
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::{Arc, Mutex};
use std::time::Duration;

const MATERIAL: &str = "ggx:alpha=0.25,kd=0.3/0.2/0.1,ks=0.05";
const RATE: f64 = 0.05;
const PORT: &str = "/dev/ttyACM-emulated";

/// The tests of this file take turns: each runs a controller thread that must answer within the
/// driver's timeout, and a job beside it (simulated camera on every core) starves it on a
/// 2-core machine.
static ONE_AT_A_TIME: Mutex<()> = Mutex::new(());

fn one_at_a_time() -> std::sync::MutexGuard<'static, ()> {
    ONE_AT_A_TIME.lock().unwrap_or_else(|e| e.into_inner())
}

/// The GRBL turntable, with the simulated one following it so that the simulated camera sees
/// the lamp where the controller put it.
struct GrblOverPty {
    grbl: GrblTurntable,
    sim: Box<dyn Turntable>,
}

impl Turntable for GrblOverPty {
    fn home(&mut self, timeout: Duration) -> HalResult<()> {
        self.grbl.home(timeout)?;
        self.sim.home(timeout)
    }
    fn move_to(&mut self, angle_deg: f64, timeout: Duration) -> HalResult<()> {
        self.grbl.move_to(angle_deg, timeout)?;
        self.sim.move_to(angle_deg, timeout)
    }
    fn angle(&mut self) -> HalResult<f64> {
        self.grbl.angle()
    }
    fn speed(&self) -> f64 {
        self.grbl.speed()
    }
    fn set_speed(&mut self, deg_per_s: f64) -> HalResult<()> {
        self.grbl.set_speed(deg_per_s)?;
        self.sim.set_speed(deg_per_s)
    }
    fn reconnect(&mut self) -> HalResult<()> {
        self.grbl.reconnect()
    }
}

/// The emulated controller behind the link, and the link's state.
struct Link {
    faults: Arc<EmulatorFaults>,
    /// Emulators of the link's successive connections (kept alive while the job runs).
    emulators: Arc<Mutex<Vec<GrblEmulator>>>,
    /// When set, reopening the port fails: it has vanished.
    gone: Arc<AtomicBool>,
}

fn emulator_config(hostile: Option<HostileLink>) -> GrblEmulatorConfig {
    GrblEmulatorConfig {
        time_scale: 2000.0,
        homing_enabled: true,
        homing_s: 1.0,
        home_position: [0.0; 3],
        hostile,
    }
}

fn open_link(
    faults: &Arc<EmulatorFaults>,
    emulators: &Arc<Mutex<Vec<GrblEmulator>>>,
    hostile: Option<HostileLink>,
    connection: u64,
) -> HalResult<Box<dyn serialport::SerialPort>> {
    let (master, slave) = serialport::TTYPort::pair().map_err(|e| HalError::DeviceAbsent {
        device: DeviceKind::MotionController,
        name: PORT.into(),
        detail: e.to_string(),
    })?;
    // Each connection rolls its own faults.
    let hostile = hostile.map(|h| HostileLink {
        seed: h.seed ^ connection.wrapping_mul(0x9e37_79b9_7f4a_7c15),
        ..h
    });
    let emu = GrblEmulator::spawn_with_faults(master, emulator_config(hostile), faults.clone());
    emulators.lock().unwrap().push(emu);
    Ok(Box::new(slave))
}

/// The simulated station of `spec` with its turntable on the GRBL emulator, and camera and
/// lamp faults at `RATE`.
fn hostile_station(spec: &JobSpec, hostile: Option<HostileLink>) -> (Station, Link) {
    let setup = SimSetup::with_scale(0.12);
    let mut cfg = setup.config(&spec.material);
    // Lamp faults strike per frame in the simulator; a rate per exposure series of RATE.
    let frames = hdr::thesis_ladder().len() as f64;
    let per_frame = 1.0 - (1.0 - RATE).powf(1.0 / frames);
    cfg.faults = hal_sim::FaultConfig {
        seed: 77,
        camera_frame_drop: RATE,
        camera_corrupted_frame: RATE,
        camera_disconnect: RATE,
        lamp_dropout: per_frame,
        lamp_flicker: per_frame,
        ..cfg.faults
    };
    let sim = SimulatedRig::with_config(spec, &setup, cfg).unwrap();
    let mut rig = sim.sim().rig();
    let faults = Arc::new(EmulatorFaults::default());
    let emulators = Arc::new(Mutex::new(Vec::new()));
    let gone = Arc::new(AtomicBool::new(false));
    let first = open_link(&faults, &emulators, hostile, 0).unwrap();
    let connections = Arc::new(AtomicU64::new(1));
    let connector: gantry_hal::grbl::Connector = {
        let (faults, emulators, gone) = (faults.clone(), emulators.clone(), gone.clone());
        Box::new(move || {
            if gone.load(Ordering::SeqCst) {
                return Err(HalError::DeviceAbsent {
                    device: DeviceKind::MotionController,
                    name: PORT.into(),
                    detail: "no such device (unplugged)".into(),
                });
            }
            let k = connections.fetch_add(1, Ordering::SeqCst);
            open_link(&faults, &emulators, hostile, k)
        })
    };
    let driver = GrblConfig {
        port: PORT.into(),
        speed_deg_per_s: 10.0,
        // Long enough that a starved emulator thread on a loaded 2-core machine is not taken for a
        // silent controller (0.75 s was not: seven timeouts in a row once ended a move of the
        // soak); injected silences cost this much each.
        command_timeout_s: 1.5,
        banner_timeout_s: 0.5,
        poll_interval_s: 0.01,
        ..GrblConfig::default()
    };
    let mut ctl = GrblController::from_port(first, Some(connector), driver).unwrap();
    ctl.reset().unwrap();
    let grbl = GrblTurntable::new(Arc::new(Mutex::new(ctl))).unwrap();
    rig.turntable = Box::new(GrblOverPty {
        grbl,
        sim: rig.turntable,
    });
    (
        Station {
            rig,
            simulator: Some(Box::new(sim)),
        },
        Link {
            faults,
            emulators,
            gone,
        },
    )
}

fn options(resume: bool) -> RunOptions {
    RunOptions {
        calibration: CalibrationSource::TrueGeometry,
        resume,
        ..RunOptions::default()
    }
}

#[test]
fn at_five_percent_of_every_device_fault_the_job_completes_and_reports_each() {
    let _turn = one_at_a_time();
    let tmp = tempfile::tempdir().unwrap();
    let positions = 8;
    let spec = JobSpec::new(MATERIAL, positions);
    let (mut station, link) = hostile_station(&spec, Some(HostileLink::uniform(2024, RATE)));
    let outcome = acquire::run(&mut station, &spec, &options(false), tmp.path()).unwrap();
    let Outcome::Finished(done) = outcome else {
        panic!("the job did not finish: {outcome:?}");
    };
    assert_eq!(done.report.positions, positions);
    let job = acquire::JobDir::new(tmp.path());
    for i in 0..positions {
        assert_eq!(
            job.check_position(i),
            acquire::PositionCheck::Done,
            "position {i}"
        );
    }
    let error = done.report.truth_table_error.as_ref().unwrap();
    assert!(
        error.median_abs_log < 0.2,
        "faults cost accuracy: {error:?}"
    );
    let faults = &done.report.faults;
    let count = |k: FaultKind| faults.by_kind.get(&k).copied().unwrap_or(0);
    let injected: BTreeMap<&str, usize> = link.faults.injected.counts().into_iter().collect();
    eprintln!(
        "hostile devices, {positions} positions: injected on the link {injected:?}; \
         {} connections; handled {:?}",
        link.emulators.lock().unwrap().len(),
        faults.by_kind
    );
    // Every fault that reaches the job is reported with its handling (the link's own faults
    // at this size are few; the soak below counts them over many moves).
    assert!(
        count(FaultKind::TurntableDisconnect) >= injected["disconnect"],
        "every disconnect is reported (and reconnected)"
    );
    assert!(
        injected["silence"] == 0 || count(FaultKind::TurntableTimeout) > 0,
        "unanswered commands are reported as timeouts"
    );
    for kind in [
        FaultKind::FrameDropped,
        FaultKind::FrameCorrupted,
        FaultKind::CameraDisconnect,
    ] {
        assert!(count(kind) > 0, "no {kind} was reported");
    }
    assert!(
        count(FaultKind::LampDropout)
            + count(FaultKind::LampFlicker)
            + count(FaultKind::SeriesInconsistent)
            > 0,
        "no lamp fault was reported"
    );
    for e in &faults.events {
        assert!(
            !e.event.detail.is_empty(),
            "a fault without its handling: {e:?}"
        );
    }
    // The report on disk lists the same events.
    let report: serde_json::Value =
        serde_json::from_slice(&std::fs::read(tmp.path().join("report.json")).unwrap()).unwrap();
    assert_eq!(
        report["faults"]["events"].as_array().unwrap().len(),
        faults.total
    );
}

/// The link's faults over many moves with the job's retry policy: every injected fault that
/// reaches the policy is handled and logged; noise, splits and merges never reach it.
#[test]
fn three_hundred_moves_over_a_hostile_link_all_arrive() {
    let _turn = one_at_a_time();
    let spec = JobSpec::new(MATERIAL, 2);
    // Silences at a quarter of the rate: each costs a whole command timeout.
    let soak = HostileLink {
        silence: RATE / 4.0,
        ..HostileLink::uniform(99, RATE)
    };
    let (mut station, link) = hostile_station(&spec, Some(soak));
    let mut log = Vec::new();
    let mut dev = acquire::Devices {
        rig: &mut station.rig,
        log: &mut log,
    };
    dev.home().unwrap();
    let moves = 300;
    for k in 0..moves {
        let angle = ((k * 37) % 180) as f64 + 0.5;
        if let Err(e) = dev.move_to(angle) {
            let tail: Vec<String> = dev
                .log
                .iter()
                .rev()
                .take(12)
                .map(|e| e.to_string())
                .collect();
            panic!("move {k} to {angle}°: {e}; last faults (newest first): {tail:#?}");
        }
    }
    let injected: BTreeMap<&str, usize> = link.faults.injected.counts().into_iter().collect();
    let mut handled: BTreeMap<FaultKind, usize> = BTreeMap::new();
    for e in &log {
        *handled.entry(e.kind).or_default() += 1;
        assert!(!e.detail.is_empty());
    }
    eprintln!(
        "hostile link soak, {moves} moves: injected {injected:?}; {} connections; handled {handled:?}",
        link.emulators.lock().unwrap().len()
    );
    for (name, n) in &injected {
        assert!(
            *n > 0,
            "no {name} fault was injected: the soak does not cover it"
        );
    }
    let count = |k: FaultKind| handled.get(&k).copied().unwrap_or(0);
    assert_eq!(
        count(FaultKind::TurntableDisconnect),
        injected["disconnect"]
    );
    assert_eq!(
        link.emulators.lock().unwrap().len(),
        1 + injected["disconnect"],
        "one reconnection per disconnect"
    );
    assert!(count(FaultKind::TurntableTimeout) > 0);
    assert!(count(FaultKind::TurntableLost) >= injected["alarm"] + injected["reset"]);
}

#[test]
fn a_port_gone_for_good_stops_the_job_with_a_clear_error_and_it_resumes() {
    let _turn = one_at_a_time();
    let tmp = tempfile::tempdir().unwrap();
    let positions = 4;
    let spec = JobSpec::new(MATERIAL, positions);
    // Every move disconnects half-way, and the port does not come back.
    let only_disconnects = HostileLink {
        seed: 5,
        disconnect: 1.0,
        ..HostileLink::default()
    };
    let (mut station, link) = hostile_station(&spec, Some(only_disconnects));
    link.gone.store(true, Ordering::SeqCst);
    let err = acquire::run(&mut station, &spec, &options(false), tmp.path()).unwrap_err();
    let text = err.to_string();
    assert!(
        matches!(err, AcquireError::Device(HalError::DeviceAbsent { .. })),
        "{text}"
    );
    assert!(
        text.contains(PORT),
        "the error does not name the port: {text}"
    );
    assert!(
        !tmp.path().join("job.lock").exists(),
        "the stopped job kept its lock"
    );
    // The port is back (a healthy controller): the job resumes and completes.
    let (mut station, _link) = hostile_station(&spec, None);
    let outcome = acquire::run(&mut station, &spec, &options(true), tmp.path()).unwrap();
    let Outcome::Finished(done) = outcome else {
        panic!("the resumed job did not finish: {outcome:?}");
    };
    assert_eq!(done.report.positions, positions);
}
