//! Geometric fits on synthetic data with known answers: noise-free data must be recovered
//! exactly, noisy data within statistical bounds, degenerate data must be typed errors.

use calib::{
    fit_extrinsics, fit_intrinsics, fit_lamp_circle, fit_sphere, BoardGeometry, CalibError,
    CameraIntrinsics, CameraPose, IntrinsicOptions, LampCircle, LampReading, TipCorrespondence,
};
use nalgebra::{Rotation3, Vector3};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, Normal};

fn camera() -> CameraIntrinsics {
    CameraIntrinsics {
        width: 640,
        height: 480,
        fx: 1500.0,
        fy: 1510.0,
        cx: 322.0,
        cy: 236.5,
        k1: -0.3,
        k2: 0.0,
        p1: 0.0,
        p2: 0.0,
        k3: 0.0,
    }
}

fn pose() -> CameraPose {
    let r = Rotation3::from_euler_angles(-1.5, 0.02, 0.01).into_inner();
    CameraPose::from_matrix(&r, &Vector3::new(0.003, -0.002, 1.0))
}

#[test]
fn sphere_centre_is_recovered() {
    let c = Vector3::new(0.0005, -0.0003, 0.0002);
    let r = 0.0254;
    let mut rng = ChaCha8Rng::seed_from_u64(1);
    let pts: Vec<[f64; 3]> = (0..30)
        .map(|_| {
            let z: f64 = rng.gen_range(-0.5..1.0);
            let ph: f64 = rng.gen_range(0.0..std::f64::consts::TAU);
            let s = (1.0 - z * z).sqrt();
            let p = c + r * Vector3::new(s * ph.cos(), s * ph.sin(), z);
            [p.x, p.y, p.z]
        })
        .collect();
    let fit = fit_sphere(&pts, 2.0 * r).unwrap();
    assert!((Vector3::from(fit.geometry.centre) - c).norm() < 1e-9);
    assert!(fit.rms_m < 1e-9);
    // Noisy readings: centre error well below the reading noise.
    let n = Normal::new(0.0, 50e-6).unwrap();
    let noisy: Vec<[f64; 3]> = pts
        .iter()
        .map(|p| p.map(|x| x + n.sample(&mut rng)))
        .collect();
    let fit = fit_sphere(&noisy, 2.0 * r).unwrap();
    assert!((Vector3::from(fit.geometry.centre) - c).norm() < 50e-6);
    assert!((fit.rms_m / 50e-6 - 1.0).abs() < 0.5, "rms {}", fit.rms_m);
}

#[test]
fn sphere_degenerate_inputs_are_typed_errors() {
    let flat: Vec<[f64; 3]> = (0..10)
        .map(|k| {
            let a = k as f64;
            [a.cos() * 0.02, a.sin() * 0.02, 0.0]
        })
        .collect();
    assert!(matches!(
        fit_sphere(&flat, 0.05),
        Err(CalibError::Degenerate(_))
    ));
    assert!(matches!(
        fit_sphere(&flat[..3], 0.05),
        Err(CalibError::TooFewPoints { .. })
    ));
    let mut nan = flat.clone();
    nan[0][2] = f64::NAN;
    nan[1][2] = 0.01;
    assert!(matches!(
        fit_sphere(&nan, 0.05),
        Err(CalibError::NonFinite(_))
    ));
    assert!(matches!(
        fit_sphere(&flat, -1.0),
        Err(CalibError::Invalid(_))
    ));
}

fn lamp_truth() -> LampCircle {
    let n = Vector3::new(0.01, -0.02, 1.0).normalize();
    let u = n.cross(&Vector3::x()).normalize();
    LampCircle {
        centre: [0.0012, 0.0008, -0.0015],
        normal: [n.x, n.y, n.z],
        radius: 0.5,
        reference: [u.x, u.y, u.z],
    }
}

#[test]
fn lamp_circle_is_recovered_with_orientation_and_reference() {
    let truth = lamp_truth();
    let readings: Vec<LampReading> = (0..30)
        .map(|k| {
            let a = 10.0 + k as f64 * 5.5;
            let p = truth.position(a);
            LampReading {
                angle_deg: a,
                position: [p.x, p.y, p.z],
            }
        })
        .collect();
    let fit = fit_lamp_circle(&readings).unwrap();
    let c = fit.circle;
    assert!((Vector3::from(c.centre) - Vector3::from(truth.centre)).norm() < 1e-9);
    assert!((c.radius - truth.radius).abs() < 1e-9);
    assert!((Vector3::from(c.normal) - Vector3::from(truth.normal)).norm() < 1e-9);
    assert!((Vector3::from(c.reference) - Vector3::from(truth.reference)).norm() < 1e-9);
    for a in [0.0, 90.0, 233.0] {
        assert!((c.position(a) - truth.position(a)).norm() < 1e-9);
    }
    // Angles running the other way flip the normal, not the positions.
    let reversed: Vec<LampReading> = readings
        .iter()
        .map(|r| LampReading {
            angle_deg: -r.angle_deg,
            position: r.position,
        })
        .collect();
    let fit = fit_lamp_circle(&reversed).unwrap();
    assert!((Vector3::from(fit.circle.normal) + Vector3::from(truth.normal)).norm() < 1e-9);
    for r in &reversed {
        assert!((fit.circle.position(r.angle_deg) - Vector3::from(r.position)).norm() < 1e-9);
    }
}

#[test]
fn lamp_degenerate_inputs_are_typed_errors() {
    let line: Vec<LampReading> = (0..10)
        .map(|k| LampReading {
            angle_deg: k as f64,
            position: [k as f64 * 0.01, 0.0, 0.0],
        })
        .collect();
    assert!(matches!(
        fit_lamp_circle(&line),
        Err(CalibError::Degenerate(_))
    ));
    assert!(matches!(
        fit_lamp_circle(&line[..2]),
        Err(CalibError::TooFewPoints { .. })
    ));
    let truth = lamp_truth();
    let same_angle: Vec<LampReading> = (0..10)
        .map(|k| {
            let p = truth.position(k as f64 * 10.0);
            LampReading {
                angle_deg: 5.0,
                position: [p.x, p.y, p.z],
            }
        })
        .collect();
    assert!(matches!(
        fit_lamp_circle(&same_angle),
        Err(CalibError::Degenerate(_))
    ));
}

fn tips(n: usize, depth: f64, planar: bool, seed: u64) -> Vec<TipCorrespondence> {
    let cam = camera();
    let pose = pose();
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let centre = pose.centre();
    (0..n)
        .map(|_| {
            let u = rng.gen_range(30.0..610.0);
            let v = rng.gen_range(30.0..450.0);
            let d = pose.dir_to_world(&cam.ray(u, v));
            let s = if planar {
                // On the world plane y = 0 (the camera looks along +y).
                -centre.y / d.y
            } else {
                1.0 + rng.gen_range(-depth..depth)
            };
            let p = centre + s * d;
            TipCorrespondence {
                world: [p.x, p.y, p.z],
                pixel: [u, v],
            }
        })
        .collect()
}

#[test]
fn extrinsics_are_recovered_from_tips() {
    let truth = pose();
    for planar in [false, true] {
        let fit = fit_extrinsics(&camera(), &tips(30, 0.05, planar, 3)).unwrap();
        let angle =
            calib::rotation_angle_between(&fit.pose.rotation_matrix(), &truth.rotation_matrix());
        assert!(angle < 1e-8, "planar {planar}: rotation error {angle}");
        assert!(
            (fit.pose.translation_vector() - truth.translation_vector()).norm() < 1e-8,
            "planar {planar}"
        );
        assert!(fit.rms_px < 1e-6);
    }
}

#[test]
fn extrinsic_degenerate_inputs_are_typed_errors() {
    let t = tips(30, 0.05, false, 4);
    assert!(matches!(
        fit_extrinsics(&camera(), &t[..5]),
        Err(CalibError::TooFewPoints { .. })
    ));
    let collinear: Vec<TipCorrespondence> = (0..10)
        .map(|k| TipCorrespondence {
            world: [0.0, k as f64 * 0.01, 0.0],
            pixel: [100.0 + k as f64, 100.0],
        })
        .collect();
    assert!(matches!(
        fit_extrinsics(&camera(), &collinear),
        Err(CalibError::Degenerate(_))
    ));
    let mut bad = t.clone();
    bad[3].pixel[0] = f64::INFINITY;
    assert!(matches!(
        fit_extrinsics(&camera(), &bad),
        Err(CalibError::NonFinite(_))
    ));
}

/// Corner pixels of `board` in views tilted by up to `tilt` radians.
fn board_views(cam: &CameraIntrinsics, board: &BoardGeometry, n: usize) -> Vec<Vec<[f64; 2]>> {
    let mut rng = ChaCha8Rng::seed_from_u64(9);
    let centre = Vector3::new(
        0.5 * board.squares_x as f64 * board.square_m,
        0.5 * board.squares_y as f64 * board.square_m,
        0.0,
    );
    (0..n)
        .map(|_| {
            let r = Rotation3::from_euler_angles(
                rng.gen_range(-0.7..0.7),
                rng.gen_range(-0.7..0.7),
                rng.gen_range(-0.3..0.3),
            );
            let t = Vector3::new(rng.gen_range(-0.01..0.01), rng.gen_range(-0.01..0.01), 0.35)
                - r * centre;
            board
                .inner_corners()
                .iter()
                .map(|p| {
                    cam.project_camera_point(&(r * Vector3::new(p[0], p[1], 0.0) + t))
                        .unwrap()
                })
                .collect()
        })
        .collect()
}

#[test]
fn intrinsics_are_recovered_from_exact_corners() {
    let cam = camera();
    let board = BoardGeometry {
        squares_x: 9,
        squares_y: 7,
        square_m: 0.008,
    };
    let views = board_views(&cam, &board, 10);
    let fit = fit_intrinsics(
        &board,
        &views,
        cam.width,
        cam.height,
        &IntrinsicOptions::default(),
    )
    .unwrap();
    let c = fit.camera;
    assert!((c.fx / cam.fx - 1.0).abs() < 1e-7 && (c.fy / cam.fy - 1.0).abs() < 1e-7);
    assert!((c.cx - cam.cx).abs() < 1e-4 && (c.cy - cam.cy).abs() < 1e-4);
    assert!((c.k1 / cam.k1 - 1.0).abs() < 1e-6);
    assert!(fit.rms_px < 1e-6);
    // The closed form alone (no distortion) is already close.
    assert!((fit.initial.fx / cam.fx - 1.0).abs() < 0.05);
    // With k2 free, the truth (k2 = 0) is found as well.
    let fit2 = fit_intrinsics(
        &board,
        &views,
        cam.width,
        cam.height,
        &IntrinsicOptions {
            model: calib::DistortionModel::K1K2,
            ..Default::default()
        },
    )
    .unwrap();
    assert!(fit2.camera.k2.abs() < 1e-4 && (fit2.camera.k1 / cam.k1 - 1.0).abs() < 1e-5);
}

#[test]
fn intrinsic_degenerate_inputs_are_typed_errors() {
    let cam = camera();
    let board = BoardGeometry {
        squares_x: 9,
        squares_y: 7,
        square_m: 0.008,
    };
    let views = board_views(&cam, &board, 4);
    let opts = IntrinsicOptions::default();
    assert!(matches!(
        fit_intrinsics(&board, &views[..2], 640, 480, &opts),
        Err(CalibError::TooFewPoints { .. })
    ));
    let mut short = views.clone();
    short[1].pop();
    assert!(matches!(
        fit_intrinsics(&board, &short, 640, 480, &opts),
        Err(CalibError::Invalid(_))
    ));
    let mut nan = views.clone();
    nan[2][5][1] = f64::NAN;
    assert!(matches!(
        fit_intrinsics(&board, &nan, 640, 480, &opts),
        Err(CalibError::NonFinite(_))
    ));
    // Three copies of one view carry no information on the focal length.
    let same = vec![views[0].clone(), views[0].clone(), views[0].clone()];
    assert!(matches!(
        fit_intrinsics(&board, &same, 640, 480, &opts),
        Err(CalibError::Degenerate(_))
    ));
}
