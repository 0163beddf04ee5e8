//! The real GRBL driver of gantry-hal against the GRBL emulator over a pseudo-terminal pair.

use gantry_hal::grbl::{GrblConfig, GrblController, GrblLamp, GrblTurntable, LampOutput};
use gantry_hal::{HalError, Lamp, LampState, Turntable};
use hal_sim::{GrblEmulator, GrblEmulatorConfig};
use std::sync::atomic::Ordering;
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

fn emu_cfg() -> GrblEmulatorConfig {
    GrblEmulatorConfig {
        time_scale: 20.0,
        homing_enabled: true,
        homing_s: 1.0,
        home_position: [-3.0, 0.0, 0.0],
        hostile: None,
    }
}

fn driver_cfg() -> GrblConfig {
    GrblConfig {
        port: "pty".into(),
        speed_deg_per_s: 10.0,
        command_timeout_s: 0.5,
        banner_timeout_s: 1.0,
        poll_interval_s: 0.01,
        lamp_warm_up_s: 0.3,
        ..GrblConfig::default()
    }
}

fn connect(cfg: GrblConfig) -> (GrblEmulator, Arc<Mutex<GrblController>>) {
    let (emu, slave) = GrblEmulator::spawn_pty(emu_cfg()).unwrap();
    let mut ctl = GrblController::from_port(Box::new(slave), None, cfg).unwrap();
    ctl.reset().unwrap();
    assert!(ctl.banner().starts_with("Grbl 1.1"), "{}", ctl.banner());
    (emu, Arc::new(Mutex::new(ctl)))
}

const LONG: Duration = Duration::from_secs(10);

#[test]
fn homing_moves_and_position_over_a_pty() {
    let (_emu, ctl) = connect(driver_cfg());
    let mut tt = GrblTurntable::new(ctl.clone()).unwrap();
    assert!(matches!(tt.move_to(10.0, LONG), Err(HalError::NotHomed)));
    // Locked in alarm after reset: G-code is refused with error:9.
    let e = ctl.lock().unwrap().command("G1 X1 F100", LONG).unwrap_err();
    assert!(matches!(e, HalError::GrblError { code: 9, .. }), "{e}");
    tt.home(LONG).unwrap();
    assert_eq!(tt.angle().unwrap(), 0.0);
    for target in [15.0, 7.5, 40.25] {
        tt.move_to(target, LONG).unwrap();
        assert!((tt.angle().unwrap() - target).abs() < 1e-3);
    }
    // Speed: 30° at 10°/s is 3 emulated s = 0.15 s of wall time at 20x.
    let t0 = Instant::now();
    tt.move_to(10.25, LONG).unwrap();
    let dt = t0.elapsed().as_secs_f64();
    assert!(dt > 0.12 && dt < 3.0, "{dt}");
}

#[test]
fn errors_and_alarms_become_typed_errors() {
    let (emu, ctl) = connect(driver_cfg());
    let mut tt = GrblTurntable::new(ctl.clone()).unwrap();
    tt.home(LONG).unwrap();
    {
        let mut c = ctl.lock().unwrap();
        let e = c.command("G99", LONG).unwrap_err();
        assert!(matches!(e, HalError::GrblError { code: 20, .. }), "{e}");
        let e = c.command("$Q", LONG).unwrap_err();
        assert!(matches!(e, HalError::GrblError { code: 3, .. }), "{e}");
        let e = c.command("G1 X1.2.3", LONG).unwrap_err();
        assert!(matches!(e, HalError::GrblError { code: 2, .. }), "{e}");
    }
    emu.faults()
        .alarm_on_next_move
        .store(true, Ordering::SeqCst);
    let e = tt.move_to(60.0, LONG).unwrap_err();
    assert!(matches!(e, HalError::LostPosition { .. }), "{e}");
    assert!(matches!(tt.move_to(1.0, LONG), Err(HalError::NotHomed)));
    tt.home(LONG).unwrap();
    tt.move_to(2.0, LONG).unwrap();
}

#[test]
fn silent_controller_times_out_quickly() {
    let (emu, ctl) = connect(driver_cfg());
    let mut tt = GrblTurntable::new(ctl.clone()).unwrap();
    tt.home(LONG).unwrap();
    emu.faults().stall.store(true, Ordering::SeqCst);
    let t0 = Instant::now();
    let e = tt.move_to(5.0, LONG).unwrap_err();
    assert!(matches!(e, HalError::Timeout { .. }), "{e}");
    assert!(t0.elapsed() < Duration::from_secs(2), "{:?}", t0.elapsed());
    let e = ctl
        .lock()
        .unwrap()
        .status(Duration::from_millis(200))
        .unwrap_err();
    assert!(matches!(e, HalError::Timeout { .. }));
}

#[test]
fn move_longer_than_its_timeout_is_held_and_reported() {
    let (_emu, ctl) = connect(driver_cfg());
    let mut tt = GrblTurntable::new(ctl.clone()).unwrap();
    tt.home(LONG).unwrap();
    // 300° at 10°/s = 30 emulated s = 1.5 s wall; allow 0.3 s.
    let e = tt.move_to(300.0, Duration::from_millis(300)).unwrap_err();
    assert!(matches!(e, HalError::Timeout { .. }), "{e}");
    let st = ctl.lock().unwrap().status(LONG).unwrap();
    assert_eq!(st.state, gantry_hal::grbl::GrblState::Hold);
    // The position is uncertain: homing (after flushing the held move) recovers.
    assert!(matches!(tt.move_to(5.0, LONG), Err(HalError::NotHomed)));
    tt.home(LONG).unwrap();
    tt.move_to(5.0, LONG).unwrap();
    assert!((tt.angle().unwrap() - 5.0).abs() < 1e-3);
}

#[test]
fn lamp_on_spindle_and_coolant_outputs() {
    for output in [
        LampOutput::Spindle { s_value: 800.0 },
        LampOutput::Flood,
        LampOutput::Mist,
    ] {
        let (emu, ctl) = connect(GrblConfig {
            lamp_output: output,
            ..driver_cfg()
        });
        let mut tt = GrblTurntable::new(ctl.clone()).unwrap();
        tt.home(LONG).unwrap();
        let mut lamp = GrblLamp::new(ctl.clone()).unwrap();
        assert_eq!(lamp.state().unwrap(), LampState::Off);
        lamp.set_on(true).unwrap();
        assert!(matches!(lamp.state().unwrap(), LampState::WarmingUp { .. }));
        let st = ctl.lock().unwrap().status(LONG).unwrap();
        let on = match output {
            LampOutput::Spindle { .. } => st.spindle_on,
            LampOutput::Flood => st.flood_on,
            LampOutput::Mist => st.mist_on,
        };
        assert!(on, "{output:?} output not reported on");
        lamp.wait_stable(LONG).unwrap();
        assert_eq!(lamp.state().unwrap(), LampState::Stable);
        // A tripped lamp supply: the controller reports the output off.
        emu.faults().drop_outputs.store(true, Ordering::SeqCst);
        std::thread::sleep(Duration::from_millis(30));
        let e = lamp.state().unwrap_err();
        assert!(matches!(e, HalError::LampDropout { .. }), "{e}");
        emu.faults().drop_outputs.store(false, Ordering::SeqCst);
        lamp.set_on(true).unwrap();
        lamp.set_on(false).unwrap();
        assert_eq!(lamp.state().unwrap(), LampState::Off);
    }
}

#[test]
fn hang_up_is_a_disconnect_and_reconnect_recovers() {
    let (emu, slave) = GrblEmulator::spawn_pty(emu_cfg()).unwrap();
    let spares: Arc<Mutex<Vec<GrblEmulator>>> = Arc::new(Mutex::new(Vec::new()));
    let keep = spares.clone();
    let connector: gantry_hal::grbl::Connector = Box::new(move || {
        let (e, s) = GrblEmulator::spawn_pty(emu_cfg()).map_err(|e| HalError::DeviceAbsent {
            device: gantry_hal::DeviceKind::MotionController,
            name: "pty".into(),
            detail: e.to_string(),
        })?;
        keep.lock().unwrap().push(e);
        Ok(Box::new(s) as Box<dyn serialport::SerialPort>)
    });
    let mut ctl =
        GrblController::from_port(Box::new(slave), Some(connector), driver_cfg()).unwrap();
    ctl.reset().unwrap();
    let ctl = Arc::new(Mutex::new(ctl));
    let mut tt = GrblTurntable::new(ctl.clone()).unwrap();
    tt.home(LONG).unwrap();
    emu.faults().hang_up.store(true, Ordering::SeqCst);
    drop(emu);
    let t0 = Instant::now();
    let e = tt.move_to(5.0, LONG).unwrap_err();
    assert!(matches!(e, HalError::Disconnected { .. }), "{e}");
    assert!(t0.elapsed() < Duration::from_secs(2));
    tt.reconnect().unwrap();
    assert_eq!(spares.lock().unwrap().len(), 1);
    assert!(matches!(tt.move_to(5.0, LONG), Err(HalError::NotHomed)));
    tt.home(LONG).unwrap();
    tt.move_to(5.0, LONG).unwrap();
    assert!((tt.angle().unwrap() - 5.0).abs() < 1e-3);
}

#[test]
fn port_without_grbl_behind_it_fails_fast_naming_it() {
    // The slave side of a pty whose master nobody serves: opened, but no banner.
    let (_master, slave) = serialport::TTYPort::pair().unwrap();
    let path = serialport::SerialPort::name(&slave).unwrap();
    drop(slave);
    let t0 = Instant::now();
    let e = GrblController::open(GrblConfig {
        port: path.clone(),
        banner_timeout_s: 0.3,
        ..driver_cfg()
    })
    .unwrap_err();
    assert!(t0.elapsed() < Duration::from_secs(2));
    assert!(matches!(e, HalError::DeviceAbsent { .. }), "{e}");
    assert!(e.to_string().contains(&path), "{e}");
}
