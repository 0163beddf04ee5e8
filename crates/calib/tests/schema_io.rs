//! Calibration file: the simulator's truth converts 1:1 and projects identically; JSON and the
//! other output files round-trip; malformed files are typed errors.

mod common;

use calib::io::{
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
fn truth_converts_one_to_one_and_projects_like_the_simulator() {
    let t = sim_truth();
    let c = common::truth_calibration(&t);
    // Same keys and values.
    let camera_json = serde_json::to_value(c.camera).unwrap();
    assert_eq!(camera_json, serde_json::to_value(t.camera).unwrap());
    for key in ["fx", "fy", "cx", "cy", "k1", "k2", "width", "height"] {
        assert!(camera_json.get(key).is_some(), "{key}");
    }
    assert_eq!(
        serde_json::to_value(c.pose).unwrap(),
        serde_json::to_value(t.pose).unwrap()
    );
    assert_eq!(
        serde_json::to_value(c.lamp).unwrap(),
        serde_json::to_value(t.lamp.circle).unwrap()
    );
    // Projection, rays and lamp positions agree with the simulator's own code.
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(2);
    for _ in 0..200 {
        let p = Vector3::new(
            rng.gen_range(-0.03..0.03),
            rng.gen_range(-0.03..0.03),
            rng.gen_range(-0.03..0.03),
        );
        let ours = c.project(&p).unwrap();
        let theirs = t
            .camera
            .project_camera_point(&t.pose.to_camera(&p))
            .unwrap();
        assert!((ours[0] - theirs[0]).abs() < 1e-9 && (ours[1] - theirs[1]).abs() < 1e-9);
        // The ray through the projection passes through the point.
        let (o, d) = c.pixel_ray_world(ours[0], ours[1]);
        let miss = (p - o).cross(&d).norm();
        assert!(miss < 1e-9, "ray misses by {miss} m");
        let a = rng.gen_range(-180.0..180.0);
        assert!((c.lamp_position(a) - t.lamp.circle.position(a)).norm() < 1e-12);
    }
    let (o, _) = c.pixel_ray_world(3.0, 4.0);
    assert!((o - t.pose.centre()).norm() < 1e-12);
}

#[test]
fn calibration_json_round_trips_and_checks_its_version() {
    let c = common::truth_calibration(&sim_truth());
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("calibration.json");
    c.write(&path).unwrap();
    assert_eq!(Calibration::read(&path).unwrap(), c);
    let text = std::fs::read_to_string(&path).unwrap();
    assert!(text.contains("\"version\": 1"));
    let v2 = text.replace("\"version\": 1", "\"version\": 2");
    assert!(matches!(
        Calibration::from_json(&v2),
        Err(CalibError::Version {
            found: 2,
            supported: 1
        })
    ));
    let broken = text.replace("\"fx\"", "\"focal\"");
    assert!(Calibration::from_json(&broken).is_err());
    let mut bad = c;
    bad.lamp.radius = f64::NAN;
    assert!(matches!(bad.validate(), Err(CalibError::NonFinite(_))));
    let mut bad = c;
    bad.pose.rotation[0][0] = 2.0;
    assert!(matches!(bad.validate(), Err(CalibError::Invalid(_))));
    let from_fields = Calibration::from_fields(
        (
            c.camera.width,
            c.camera.height,
            c.camera.fx,
            c.camera.fy,
            c.camera.cx,
            c.camera.cy,
            c.camera.k1,
            c.camera.k2,
        ),
        c.pose.rotation,
        c.pose.translation,
        c.lamp.centre,
        c.lamp.normal,
        c.lamp.radius,
        c.lamp.reference,
        c.sphere.centre,
        c.sphere.radius,
    )
    .unwrap();
    assert_eq!(from_fields, c);
}

#[test]
fn distortion_inverts() {
    let c = common::truth_calibration(&sim_truth()).camera;
    for &(x, y) in &[(0.0, 0.0), (0.05, -0.03), (-0.07, 0.06), (0.2, 0.1)] {
        let (xd, yd) = c.distort(x, y);
        let (xu, yu) = c.undistort(xd, yd);
        assert!((xu - x).abs() < 1e-14 && (yu - y).abs() < 1e-14);
    }
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
