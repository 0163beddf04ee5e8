//! The target protocol: planned board poses and what they determine (exact corner pixels of the
//! simulator's camera, no rendering).

use calib::{
    fit_intrinsics, plan_board_poses, CalibError, CameraIntrinsics, IntrinsicOptions,
    TargetProtocol,
};
use nalgebra::Vector3;
use rand::SeedableRng;
use rand_distr::{Distribution, Normal};

fn sim_camera(scale: f64) -> CameraIntrinsics {
    let rig = hal_sim::SimRig::new(
        hal_sim::SimConfig::with_scale(scale),
        std::sync::Arc::new(brdf::analytic::Lambert { kd: [0.5; 3] }),
    )
    .unwrap();
    rig.truth().camera
}

fn corner_pixels(
    p: &TargetProtocol,
    cam: &CameraIntrinsics,
    pose: &calib::BoardPose,
) -> Vec<[f64; 2]> {
    let r = pose.rotation_matrix();
    let t = Vector3::from(pose.translation);
    p.board
        .inner_corners()
        .iter()
        .map(|c| {
            cam.project_camera_point(&(r * Vector3::new(c[0], c[1], 0.0) + t))
                .unwrap()
        })
        .collect()
}

#[test]
fn planned_poses_follow_the_protocol() {
    let cam = sim_camera(1.0);
    let p = TargetProtocol::default();
    let poses = plan_board_poses(&p, &cam, 7).unwrap();
    assert_eq!(poses.len(), p.views);
    let (w, h) = (cam.width as f64, cam.height as f64);
    let mut quadrants = [0usize; 4];
    for pose in &poses {
        let px = corner_pixels(&p, &cam, pose);
        let (mut lo, mut hi) = ([f64::INFINITY; 2], [f64::NEG_INFINITY; 2]);
        for q in &px {
            for k in 0..2 {
                lo[k] = lo[k].min(q[k]);
                hi[k] = hi[k].max(q[k]);
            }
        }
        // Inside the image, and spanning the requested fraction in one direction.
        assert!(lo[0] > 0.0 && lo[1] > 0.0 && hi[0] < w - 1.0 && hi[1] < h - 1.0);
        let span = ((hi[0] - lo[0]) / w).max((hi[1] - lo[1]) / h);
        assert!((span - p.fill).abs() < 0.01, "span {span}");
        // Tilt = angle between the board normal and the optical axis.
        let normal = pose.rotation_matrix() * Vector3::z();
        let tilt = normal.angle(&Vector3::z());
        assert!(
            tilt > p.tilt_min_rad - 1e-9 && tilt < p.tilt_max_rad + 1e-9,
            "tilt {}",
            tilt.to_degrees()
        );
        // Which way the board leans: the tilt axes must go round the optical axis.
        let q = match (normal.x >= 0.0, normal.y >= 0.0) {
            (true, true) => 0,
            (false, true) => 1,
            (false, false) => 2,
            (true, false) => 3,
        };
        quadrants[q] += 1;
    }
    assert!(quadrants.iter().all(|&n| n >= p.views / 6), "{quadrants:?}");
    // Reproducible, and seeded.
    assert_eq!(plan_board_poses(&p, &cam, 7).unwrap(), poses);
    assert_ne!(plan_board_poses(&p, &cam, 8).unwrap(), poses);
}

#[test]
fn invalid_protocols_are_typed_errors() {
    let cam = sim_camera(0.25);
    let ok = TargetProtocol::for_sensor(cam.width);
    let cases = [
        TargetProtocol { views: 2, ..ok },
        TargetProtocol {
            tilt_max_rad: f64::NAN,
            ..ok
        },
        TargetProtocol {
            tilt_min_rad: 1.0,
            tilt_max_rad: 0.5,
            ..ok
        },
        TargetProtocol { fill: 1.2, ..ok },
        TargetProtocol {
            frames_per_view: 0,
            ..ok
        },
        TargetProtocol {
            flat_frames: 65,
            ..ok
        },
    ];
    for c in cases {
        let e = plan_board_poses(&c, &cam, 1).unwrap_err();
        assert!(
            matches!(
                e,
                CalibError::TooFewPoints { .. } | CalibError::NonFinite(_) | CalibError::Invalid(_)
            ),
            "{e}"
        );
    }
}

#[test]
fn protocol_determines_the_camera_from_exact_and_noisy_corners() {
    // Full-resolution camera of the simulator (f = 12 150 px, 6° field of view).
    let cam = sim_camera(1.0);
    let p = TargetProtocol {
        views: 12,
        ..TargetProtocol::default()
    };
    let poses = plan_board_poses(&p, &cam, 3).unwrap();
    let exact: Vec<Vec<[f64; 2]>> = poses.iter().map(|q| corner_pixels(&p, &cam, q)).collect();
    let fit = |views: &[Vec<[f64; 2]>]| {
        fit_intrinsics(
            &p.board,
            views,
            cam.width,
            cam.height,
            &IntrinsicOptions {
                model: calib::DistortionModel::K1K2,
                ..Default::default()
            },
        )
        .unwrap()
        .camera
    };
    // Exact corners: the fit recovers every parameter (k2 included).
    let c = fit(&exact);
    assert!((c.fx / cam.fx - 1.0).abs() < 1e-6, "{c:?}");
    assert!((c.cx - cam.cx).hypot(c.cy - cam.cy) < 0.01, "{c:?}");
    assert!(
        (c.k1 - cam.k1).abs() < 1e-3 && (c.k2 - cam.k2).abs() < 0.5,
        "{c:?}"
    );
    // Corner noise of the detector on full-resolution frames (0.02–0.03 px): the focal lengths
    // are far inside the 0.2 %; the principal point is the weak parameter (a few px
    // with these 12 views; its standard deviation is ~3 px, docs/calib.md).
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(11);
    let n = Normal::new(0.0, 0.03).unwrap();
    let noisy: Vec<Vec<[f64; 2]>> = exact
        .iter()
        .map(|v| {
            v.iter()
                .map(|q| [q[0] + n.sample(&mut rng), q[1] + n.sample(&mut rng)])
                .collect()
        })
        .collect();
    let c = fit_intrinsics(
        &p.board,
        &noisy,
        cam.width,
        cam.height,
        &IntrinsicOptions::default(),
    )
    .unwrap()
    .camera;
    assert!((c.fx / cam.fx - 1.0).abs() < 2e-4, "{c:?}");
    assert!((c.fy / cam.fy - 1.0).abs() < 2e-4, "{c:?}");
    assert!((c.k1 / cam.k1 - 1.0).abs() < 0.05, "{c:?}");
    assert!((c.cx - cam.cx).hypot(c.cy - cam.cy) < 8.0, "{c:?}");
}
