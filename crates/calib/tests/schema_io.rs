//! Calibration file: the simulator's truth converts 1:1 and its pixel rays pass through the points
//! they project from; JSON and the other output files round-trip; malformed files are typed
//! errors.

use calib::{
    digitizer_csv, frame_png16, parse_digitizer_csv, read_digitizer_csv, read_frame_png16,
    write_atomic, DigitizerLog,
};
use calib::{CalibError, Calibration, LampReading, TipCorrespondence};
use gantry_hal::{BayerFrame, BayerPattern};
use hal_sim::{SimConfig, SimRig};
use nalgebra::Vector3;
use rand::{Rng, SeedableRng};
use std::path::Path;
use std::sync::Arc;

fn sim_truth() -> hal_sim::SceneTruth {
    SimRig::new(
        SimConfig::with_scale(0.1),
        Arc::new(brdf::analytic::Lambert { kd: [0.5; 3] }),
    )
    .unwrap()
    .truth()
    .clone()
}

#[test]
fn truth_converts_one_to_one_and_rays_pass_through_projections() {
    let t = sim_truth();
    let c = calib::calibration_from_truth(&t).unwrap();
    assert_eq!(c.version, calib::CALIBRATION_VERSION);
    assert_eq!(
        (c.camera, c.pose, c.lamp, c.sphere),
        (t.camera, t.pose, t.lamp.circle, t.sphere)
    );
    assert_eq!(c.fit, None);
    // The ray through a world point's projection passes through the point.
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(2);
    for _ in 0..200 {
        let p = Vector3::new(
            rng.gen_range(-0.03..0.03),
            rng.gen_range(-0.03..0.03),
            rng.gen_range(-0.03..0.03),
        );
        let px = c.project(&p).unwrap();
        let (o, d) = c.pixel_ray_world(px[0], px[1]);
        let miss = (p - o).cross(&d).norm();
        assert!(miss < 1e-9, "ray misses by {miss} m");
    }
    let (o, _) = c.pixel_ray_world(3.0, 4.0);
    assert!((o - t.pose.centre()).norm() < 1e-12);
    // An invalid truth is refused with the geometry's error kind.
    let mut bad = t.clone();
    bad.sphere.radius = f64::NAN;
    assert!(matches!(
        calib::calibration_from_truth(&bad),
        Err(CalibError::NonFinite("sphere"))
    ));
}

#[test]
fn calibration_json_round_trips_and_checks_its_version() {
    let c = calib::calibration_from_truth(&sim_truth()).unwrap();
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("calibration.json");
    c.write(&path).unwrap();
    assert_eq!(Calibration::read(&path).unwrap(), c);
    let text = std::fs::read_to_string(&path).unwrap();
    assert!(text.contains("\"version\": 2"));
    // Zero tangential and r⁶ terms are not written: the camera has the version-1 keys.
    assert!(!text.contains("\"p1\"") && !text.contains("\"k3\""));
    let v3 = text.replace("\"version\": 2", "\"version\": 3");
    assert!(matches!(
        Calibration::from_json(&v3),
        Err(CalibError::Version {
            found: 3,
            supported: 2
        })
    ));
    // A version-1 file (two radial terms) still loads, as version 2 with p1 = p2 = k3 = 0.
    let v1 = text.replace("\"version\": 2", "\"version\": 1");
    let old = Calibration::from_json(&v1).unwrap();
    assert_eq!(old, c);
    assert_eq!(old.version, calib::CALIBRATION_VERSION);
    // The five terms round-trip.
    let mut five = c;
    five.camera.p1 = 1.5e-3;
    five.camera.p2 = -3e-4;
    five.camera.k3 = 0.25;
    let back = Calibration::from_json(&five.to_json().unwrap()).unwrap();
    assert_eq!(back, five);
    assert_eq!(back.camera.distortion()[2..], [1.5e-3, -3e-4, 0.25]);
    let broken = text.replace("\"fx\"", "\"focal\"");
    assert!(Calibration::from_json(&broken).is_err());
    let mut bad = c;
    bad.lamp.radius = f64::NAN;
    assert!(matches!(bad.validate(), Err(CalibError::NonFinite(_))));
    let mut bad = c;
    bad.pose.rotation[0][0] = 2.0;
    assert!(matches!(bad.validate(), Err(CalibError::Invalid(_))));
}

#[test]
fn target_png_round_trips_the_raw_frame() {
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(1);
    let data: Vec<u16> = (0..40 * 30).map(|_| rng.gen_range(0..1024)).collect();
    let frame = BayerFrame::new(40, 30, 10, BayerPattern::Rggb, data, 0.5, 0.0, 25.0, 3).unwrap();
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("t.png");
    write_atomic(&path, &frame_png16(&frame).unwrap()).unwrap();
    let back = read_frame_png16(&path, 10, BayerPattern::Rggb).unwrap();
    assert_eq!(back.data, frame.data);
    assert_eq!((back.width, back.height), (40, 30));
    // The stored samples use the 16-bit range.
    let img = image::open(&path).unwrap().into_luma16();
    assert_eq!(img.get_pixel(0, 0).0[0], frame.data[0] << 6);
}

#[test]
fn digitizer_csv_round_trips_and_rejects_malformed_rows() {
    let log = DigitizerLog {
        tips: vec![TipCorrespondence {
            world: [0.1, -0.2, 1.0 / 3.0],
            pixel: [12.5, 700.125],
        }],
        lamp: vec![LampReading {
            angle_deg: 37.5,
            position: [0.5, 1e-7, -0.25],
        }],
        sphere_points: vec![[0.01, 0.02, 0.03], [0.0, 0.0, 0.0254]],
        sphere_diameter_m: 0.0508,
    };
    let text = digitizer_csv(&log);
    assert_eq!(parse_digitizer_csv(&text, Path::new("x")).unwrap(), log);
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("digitizer.csv");
    write_atomic(&path, text.as_bytes()).unwrap();
    assert_eq!(read_digitizer_csv(&path).unwrap(), log);
    for bad in [
        text.replace("tip,0", "tap,0"),
        text.replace("37.5", "NaN"),
        text.replace("37.5", "abc"),
        text.replace("caliper,0,,0.0508,,,,\n", ""),
        text.replace("kind,", "sort,"),
        text.replace("sphere,0,,0.01,0.02,0.03,,", "sphere,0,,0.01,0.02"),
    ] {
        assert!(
            matches!(
                parse_digitizer_csv(&bad, Path::new("x")),
                Err(CalibError::Parse { .. })
            ),
            "{bad}"
        );
    }
}
