//! Every injected fault surfaces as its typed error, reproducibly.

use brdf::analytic::Lambert;
use gantry_hal::{HalError, LampState};
use hal_sim::{FaultConfig, SimConfig, SimRig};
use std::sync::Arc;
use std::time::Duration;

const T: Duration = Duration::from_secs(3600);

fn rig_with(faults: FaultConfig) -> SimRig {
    let mut cfg = SimConfig::with_scale(0.05);
    cfg.lamp.warm_up_s = 0.0;
    cfg.faults = faults;
    SimRig::new(cfg, Arc::new(Lambert { kd: [0.5; 3] })).unwrap()
}

fn lamp_on_and_homed(r: &mut gantry_hal::Rig) {
    r.turntable.home(T).unwrap();
    r.lamp.set_on(true).unwrap();
    r.lamp.wait_stable(T).unwrap();
}

#[test]
fn turntable_timeout() {
    let rig = rig_with(FaultConfig {
        turntable_timeout: 1.0,
        ..Default::default()
    });
    let mut r = rig.rig();
    r.turntable.home(T).unwrap();
    let t0 = r.clock.now();
    let e = r
        .turntable
        .move_to(30.0, Duration::from_secs(60))
        .unwrap_err();
    assert!(matches!(e, HalError::Timeout { .. }), "{e}");
    assert_eq!(r.clock.now() - t0, Duration::from_secs(60));
    let stuck = rig.true_turntable_angle();
    assert!(stuck > 0.0 && stuck < 30.0, "stalled part-way at {stuck}");
    assert!(matches!(r.turntable.angle(), Err(HalError::NotHomed)));
    r.turntable.home(T).unwrap();
}

#[test]
fn move_slower_than_the_timeout_times_out_without_faults() {
    let rig = rig_with(FaultConfig::default());
    let mut r = rig.rig();
    r.turntable.home(T).unwrap();
    // 90° at 2°/s needs 45 s.
    let e = r
        .turntable
        .move_to(90.0, Duration::from_secs(10))
        .unwrap_err();
    assert!(matches!(e, HalError::Timeout { .. }));
    r.turntable.home(T).unwrap();
    r.turntable.move_to(90.0, T).unwrap();
    assert_eq!(r.turntable.angle().unwrap(), 90.0);
}

#[test]
fn turntable_lost_steps_requires_homing() {
    let rig = rig_with(FaultConfig {
        turntable_lost_steps: 1.0,
        ..Default::default()
    });
    let mut r = rig.rig();
    assert!(matches!(
        r.turntable.move_to(5.0, T),
        Err(HalError::NotHomed)
    ));
    r.turntable.home(T).unwrap();
    let e = r.turntable.move_to(20.0, T).unwrap_err();
    assert!(matches!(e, HalError::LostPosition { .. }), "{e}");
    assert!((rig.true_turntable_angle() - 20.0).abs() > 0.01);
    assert!(matches!(r.turntable.angle(), Err(HalError::NotHomed)));
    assert!(matches!(
        r.turntable.move_to(21.0, T),
        Err(HalError::NotHomed)
    ));
    r.turntable.home(T).unwrap();
    assert_eq!(r.turntable.angle().unwrap(), 0.0);
}

#[test]
fn camera_frame_drop() {
    let rig = rig_with(FaultConfig {
        camera_frame_drop: 1.0,
        ..Default::default()
    });
    let mut r = rig.rig();
    let e = r.camera.capture(T).unwrap_err();
    assert!(
        matches!(e, HalError::FrameDropped { frame_number: 1 }),
        "{e}"
    );
    let e = r.camera.capture(T).unwrap_err();
    assert!(
        matches!(e, HalError::FrameDropped { frame_number: 2 }),
        "{e}"
    );
}

#[test]
fn camera_disconnect_persists_until_reconnect() {
    let rig = rig_with(FaultConfig {
        camera_disconnect: 1.0,
        ..Default::default()
    });
    let mut r = rig.rig();
    let e = r.camera.capture(T).unwrap_err();
    assert!(matches!(e, HalError::Disconnected { .. }), "{e}");
    assert!(matches!(
        r.camera.set_exposure(0.01),
        Err(HalError::Disconnected { .. })
    ));
    assert!(matches!(
        r.camera.sensor_temperature_c(),
        Err(HalError::Disconnected { .. })
    ));
    r.camera.reconnect().unwrap();
    r.camera.set_exposure(0.01).unwrap();
}

#[test]
fn camera_corrupted_frame() {
    let rig = rig_with(FaultConfig {
        camera_corrupted_frame: 1.0,
        ..Default::default()
    });
    let mut r = rig.rig();
    let e = r.camera.capture(T).unwrap_err();
    assert!(matches!(e, HalError::CorruptedFrame { .. }), "{e}");
}

#[test]
fn lamp_dropout_is_reported_and_frames_go_dark() {
    let rig = rig_with(FaultConfig {
        lamp_dropout: 1.0,
        ..Default::default()
    });
    let mut r = rig.rig();
    lamp_on_and_homed(&mut r);
    r.turntable.move_to(90.0, T).unwrap();
    r.camera.set_exposure(0.5).unwrap();
    let f = r.camera.capture(T).unwrap();
    let e = r.lamp.state().unwrap_err();
    assert!(matches!(e, HalError::LampDropout { .. }), "{e}");
    assert_eq!(r.lamp.state().unwrap(), LampState::Off);
    // With the lamp out the frame holds only stray light and dark signal.
    let max = *f.data.iter().max().unwrap();
    assert!(max < 40, "max {max}");
}

#[test]
fn lamp_flicker_changes_the_intensity_and_is_reported() {
    let faults = FaultConfig {
        lamp_flicker: 1.0,
        lamp_flicker_magnitude: 0.2,
        ..Default::default()
    };
    let flicker = rig_with(faults);
    let steady = rig_with(FaultConfig::default());
    let grab = |rig: &SimRig| {
        let mut r = rig.rig();
        lamp_on_and_homed(&mut r);
        r.turntable.move_to(90.0, T).unwrap();
        r.camera.set_exposure(0.3).unwrap();
        let f = r.camera.capture(T).unwrap();
        (f, r.lamp.state())
    };
    let (f1, s1) = grab(&flicker);
    let (f0, s0) = grab(&steady);
    let change = match s1 {
        Err(HalError::LampFlicker {
            relative_change, ..
        }) => relative_change,
        other => panic!("expected flicker, got {other:?}"),
    };
    assert_eq!(change.abs(), 0.2);
    assert_eq!(s0.unwrap(), LampState::Stable);
    let signal = |f: &gantry_hal::BayerFrame| f.data.iter().map(|&v| v as f64 - 4.0).sum::<f64>();
    let ratio = signal(&f1) / signal(&f0);
    assert!(
        (ratio - (1.0 + change)).abs() < 0.02,
        "ratio {ratio}, change {change}"
    );
}

#[test]
fn faults_follow_their_seed() {
    let pattern = |seed: u64| {
        let rig = rig_with(FaultConfig {
            seed,
            camera_frame_drop: 0.3,
            ..Default::default()
        });
        let mut r = rig.rig();
        (0..40)
            .map(|_| r.camera.capture(T).is_err())
            .collect::<Vec<_>>()
    };
    let a = pattern(9);
    assert_eq!(a, pattern(9));
    assert_ne!(a, pattern(10));
    let drops = a.iter().filter(|&&d| d).count();
    assert!((4..=22).contains(&drops), "{drops} drops of 40 at p = 0.3");
}

#[test]
fn invalid_fault_probability_is_rejected() {
    let mut cfg = SimConfig::with_scale(0.05);
    cfg.faults.lamp_flicker = 1.5;
    let e = SimRig::new(cfg, Arc::new(Lambert { kd: [0.5; 3] })).unwrap_err();
    assert!(e.to_string().contains("lamp_flicker"), "{e}");
}
