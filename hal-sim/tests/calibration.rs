//! Calibration scenes: checkerboard images agree with their true corner positions; the contact
//! digitizer's readings scatter around the true geometry with the configured noise.

use brdf::analytic::Lambert;
use hal_sim::{Checkerboard, SimConfig, SimRig, TargetPose};
use nalgebra::Vector3;
use std::sync::Arc;

fn rig(scale: f64) -> SimRig {
    SimRig::new(
        SimConfig::with_scale(scale),
        Arc::new(Lambert { kd: [0.5; 3] }),
    )
    .unwrap()
}

#[test]
fn checkerboard_squares_appear_where_the_true_pose_projects_them() {
    let rig = rig(0.25);
    let board = Checkerboard::default();
    let cam = rig.truth().camera;
    let poses = TargetPose::varied(&board, 4, 1.0, 3);
    for pose in &poses {
        let cap = rig.capture_checkerboard(&board, pose, 0.25).unwrap();
        let corners: Vec<[f64; 2]> = cap.corners_px.iter().map(|c| c.unwrap()).collect();
        assert_eq!(corners.len(), (board.squares_x - 1) * (board.squares_y - 1));
        assert!(corners.iter().all(|c| c[0] > 2.0
            && c[1] > 2.0
            && c[0] < cam.width as f64 - 3.0
            && c[1] < cam.height as f64 - 3.0));
        // Square centres: bright for white, dark for black, in the raw frame (2x2 mean over the
        // Bayer cell around the projected centre).
        let s = board.square_m;
        let (mut white, mut black) = (Vec::new(), Vec::new());
        for j in 0..board.squares_y {
            for i in 0..board.squares_x {
                let p = [(i as f64 + 0.5) * s, (j as f64 + 0.5) * s, 0.0];
                let px = cam.project_camera_point(&pose.to_camera(&p)).unwrap();
                let (x, y) = (px[0].round() as usize & !1, px[1].round() as usize & !1);
                let f = &cap.frame;
                let v = (f.get(x, y) as f64
                    + f.get(x + 1, y) as f64
                    + f.get(x, y + 1) as f64
                    + f.get(x + 1, y + 1) as f64)
                    / 4.0;
                if (i + j) % 2 == 0 {
                    black.push(v)
                } else {
                    white.push(v)
                }
            }
        }
        let min_white = white.iter().cloned().fold(f64::MAX, f64::min);
        let max_black = black.iter().cloned().fold(0.0, f64::max);
        assert!(
            min_white > 4.0 * max_black,
            "white ≥ {min_white}, black ≤ {max_black}"
        );
    }
}

#[test]
fn checkerboard_pose_facing_centres_the_board() {
    let board = Checkerboard::default();
    let pose = TargetPose::facing(&board, 1.0, 0.3, -0.2, 0.0, 0.0);
    let c = pose.to_camera(&board.centre());
    assert!((c - Vector3::new(0.0, 0.0, 1.0)).norm() < 1e-12);
}

#[test]
fn digitizer_readings_scatter_with_the_configured_noise() {
    let rig = rig(0.1);
    let truth = rig.truth().clone();
    let sigma = 2e-4;
    let mut dig = rig.digitizer(sigma, 17);
    let angles: Vec<f64> = (0..300).map(|k| k as f64 * 0.55).collect();
    let lamp = dig.lamp_positions(&angles);
    let rms = (angles
        .iter()
        .zip(&lamp)
        .map(|(&a, m)| (truth.lamp.circle.position(a) - Vector3::from(*m)).norm_squared())
        .sum::<f64>()
        / (3.0 * angles.len() as f64))
        .sqrt();
    assert!((rms / sigma - 1.0).abs() < 0.1, "lamp rms {rms}");
    let pts = dig.sphere_surface(400);
    let c = Vector3::from(truth.sphere.centre);
    let radial: Vec<f64> = pts
        .iter()
        .map(|p| (Vector3::from(*p) - c).norm() - truth.sphere.radius)
        .collect();
    let mean = radial.iter().sum::<f64>() / radial.len() as f64;
    let sd = (radial.iter().map(|r| (r - mean).powi(2)).sum::<f64>() / radial.len() as f64).sqrt();
    assert!(
        mean.abs() < 3.0 * sigma / 20.0 && (sd / sigma - 1.0).abs() < 0.15,
        "{mean} {sd}"
    );
    // Tip observations: the true point projects onto the observed pixel up to the pixel noise.
    let obs = dig.tip_observations(200, 0.05, 0.3);
    let mut err2 = 0.0;
    for o in &obs {
        let p = truth.pose.to_camera(&Vector3::from(o.true_point));
        let px = truth.camera.project_camera_point(&p).unwrap();
        err2 += (px[0] - o.pixel[0]).powi(2) + (px[1] - o.pixel[1]).powi(2);
    }
    let rms_px = (err2 / (2.0 * obs.len() as f64)).sqrt();
    assert!((rms_px / 0.3 - 1.0).abs() < 0.15, "pixel rms {rms_px}");
    // Same seed, same readings.
    let mut again = rig.digitizer(sigma, 17);
    assert_eq!(again.lamp_positions(&angles), lamp);
}

#[test]
fn ground_truth_serialises() {
    let rig = rig(0.1);
    let json = serde_json::to_string(rig.truth()).unwrap();
    let back: hal_sim::SceneTruth = serde_json::from_str(&json).unwrap();
    assert_eq!(&back, rig.truth());
    let cfg = SimConfig::default();
    let text = toml::to_string(&cfg).unwrap();
    let parsed: SimConfig = toml::from_str(&text).unwrap();
    assert_eq!(parsed, cfg);
}

#[test]
fn example_rig_file_builds_a_simulated_rig() {
    let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../docs/rig.example.toml");
    let mut cfg = gantry_hal::RigConfig::load(&path).unwrap();
    assert_eq!(cfg.backend, gantry_hal::Backend::Sim);
    let sim = hal_sim::SimConfig::from_table(cfg.sim.as_ref().unwrap()).unwrap();
    assert_eq!(
        sim,
        SimConfig::default(),
        "the example documents the defaults"
    );
    cfg.sim
        .as_mut()
        .unwrap()
        .insert("scale".into(), toml::Value::Float(0.05));
    let rig = SimRig::from_rig_config(&cfg).unwrap();
    assert_eq!(rig.truth().camera.width, 65);
}
