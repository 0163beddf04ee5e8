//! Simulated calibration inputs from `hal-sim` with the default noise of this crate's
//! validation (shared by the integration tests and the `calibrate_sim` example).
#![allow(dead_code)]

use calib::{BoardGeometry, Calibration, CalibrationInputs, DigitizerProtocol, TargetProtocol};
use hal_sim::{Checkerboard, SceneTruth, SimConfig, SimRig};
use std::sync::Arc;

/// Default simulated measurement noise (the digitizer's, the operator's and the caliper's).
pub use calib::SessionNoise as SimNoise;

/// Simulated run: inputs, ground truth in the calibration schema, true corner pixels.
pub struct SimData {
    pub inputs: CalibrationInputs,
    pub truth: Calibration,
    pub true_corners: Vec<Vec<[f64; 2]>>,
    pub scene: SceneTruth,
}

/// Board geometry of a simulator checkerboard.
pub fn board_geometry(b: &Checkerboard) -> BoardGeometry {
    BoardGeometry {
        squares_x: b.squares_x,
        squares_y: b.squares_y,
        square_m: b.square_m,
    }
}

/// The target protocol of the simulated runs: calib's default for the sensor width, with
/// `views` images.
pub fn protocol(width: usize, views: usize) -> TargetProtocol {
    TargetProtocol {
        views,
        ..TargetProtocol::for_sensor(width)
    }
}

/// Builds calibration inputs from the default simulated rig at sensor `scale` with `views`
/// checkerboard images (calib's default protocol for the sensor), seeded.
pub fn simulate(scale: f64, views: usize, seed: u64, noise: SimNoise) -> SimData {
    simulate_with(scale, seed, noise, None, |w| protocol(w, views))
}

/// [`simulate`] with a chosen target protocol (from the sensor width) and digitizer protocol.
pub fn simulate_with(
    scale: f64,
    seed: u64,
    noise: SimNoise,
    digitizer: Option<DigitizerProtocol>,
    target: impl Fn(usize) -> TargetProtocol,
) -> SimData {
    let cfg = SimConfig {
        seed,
        ..SimConfig::with_scale(scale)
    };
    simulate_config(cfg, seed, noise, digitizer, target)
}

/// [`simulate_with`] on a rig of configuration `cfg` (sensor noise, blur...).
pub fn simulate_config(
    cfg: SimConfig,
    seed: u64,
    noise: SimNoise,
    digitizer: Option<DigitizerProtocol>,
    target: impl Fn(usize) -> TargetProtocol,
) -> SimData {
    let rig = SimRig::new(cfg, Arc::new(brdf::analytic::Lambert { kd: [0.5; 3] })).unwrap();
    let target = target(rig.truth().camera.width);
    let session =
        calib::simulate_session(&rig, &target, &digitizer.unwrap_or_default(), &noise, seed)
            .unwrap();
    SimData {
        inputs: session.inputs,
        truth: session.truth,
        true_corners: session.true_corners,
        scene: rig.truth().clone(),
    }
}

/// Errors of a calibration against the truth, in the units of the issue.
#[derive(Debug, Clone, Copy)]
pub struct Errors {
    pub fx_rel: f64,
    pub fy_rel: f64,
    pub principal_px: f64,
    pub k1_rel: f64,
    pub k2_abs: f64,
    pub rotation_deg: f64,
    pub translation_mm: f64,
    pub camera_centre_mm: f64,
    pub lamp_centre_mm: f64,
    pub lamp_radius_mm: f64,
    pub lamp_normal_deg: f64,
    pub lamp_reference_deg: f64,
    pub sphere_centre_mm: f64,
    /// Largest image distance between where the calibration and the truth project points of
    /// the sphere's visible hemisphere, pixels.
    pub sphere_projection_px: f64,
    /// Largest distance, at the sphere, between the calibrated and the true ray of a pixel
    /// (pixels over the whole sensor), mm.
    pub ray_at_sphere_mm: f64,
}

pub fn errors(c: &Calibration, t: &Calibration) -> Errors {
    use nalgebra::Vector3;
    let (a, b) = (&c.camera, &t.camera);
    let v = |p: [f64; 3]| Vector3::from(p);
    Errors {
        fx_rel: (a.fx / b.fx - 1.0).abs(),
        fy_rel: (a.fy / b.fy - 1.0).abs(),
        principal_px: (a.cx - b.cx).hypot(a.cy - b.cy),
        k1_rel: (a.k1 / b.k1 - 1.0).abs(),
        k2_abs: (a.k2 - b.k2).abs(),
        rotation_deg: calib::rotation_angle_between(
            &c.pose.rotation_matrix(),
            &t.pose.rotation_matrix(),
        )
        .to_degrees(),
        translation_mm: (v(c.pose.translation) - v(t.pose.translation)).norm() * 1e3,
        camera_centre_mm: (c.pose.centre() - t.pose.centre()).norm() * 1e3,
        lamp_centre_mm: (v(c.lamp.centre) - v(t.lamp.centre)).norm() * 1e3,
        lamp_radius_mm: (c.lamp.radius - t.lamp.radius).abs() * 1e3,
        lamp_normal_deg: v(c.lamp.normal).angle(&v(t.lamp.normal)).to_degrees(),
        lamp_reference_deg: v(c.lamp.reference).angle(&v(t.lamp.reference)).to_degrees(),
        sphere_centre_mm: (v(c.sphere.centre) - v(t.sphere.centre)).norm() * 1e3,
        sphere_projection_px: sphere_projection_error(c, t),
        ray_at_sphere_mm: ray_error_at_sphere(c, t) * 1e3,
    }
}

fn sphere_projection_error(c: &Calibration, t: &Calibration) -> f64 {
    use nalgebra::Vector3;
    let centre = Vector3::from(t.sphere.centre);
    let towards_camera = (t.pose.centre() - centre).normalize();
    let mut worst: f64 = 0.0;
    for i in 0..12 {
        for j in 0..24 {
            let th = (i as f64 + 0.5) / 12.0 * std::f64::consts::FRAC_PI_2;
            let ph = j as f64 / 24.0 * std::f64::consts::TAU;
            let d = Vector3::new(th.sin() * ph.cos(), th.sin() * ph.sin(), th.cos());
            // Rotate +z onto the direction towards the camera.
            let rot = nalgebra::Rotation3::rotation_between(&Vector3::z(), &towards_camera)
                .unwrap_or_else(nalgebra::Rotation3::identity);
            let p = centre + t.sphere.radius * (rot * d);
            let a = c.project(&p).unwrap();
            let b = t.project(&p).unwrap();
            worst = worst.max((a[0] - b[0]).hypot(a[1] - b[1]));
        }
    }
    worst
}

fn ray_error_at_sphere(c: &Calibration, t: &Calibration) -> f64 {
    use nalgebra::Vector3;
    let centre = Vector3::from(t.sphere.centre);
    let (w, h) = (t.camera.width as f64, t.camera.height as f64);
    let mut worst: f64 = 0.0;
    for i in 0..=8 {
        for j in 0..=8 {
            let (u, v) = (i as f64 / 8.0 * (w - 1.0), j as f64 / 8.0 * (h - 1.0));
            let (o1, d1) = t.pixel_ray_world(u, v);
            let (o2, d2) = c.pixel_ray_world(u, v);
            // Points of both rays at the sphere centre's depth along the true ray.
            let s1 = (centre - o1).dot(&d1);
            let p1 = o1 + s1 * d1;
            let s2 = (p1 - o2).dot(&d2);
            let p2 = o2 + s2 * d2;
            worst = worst.max((p1 - p2).norm());
        }
    }
    worst
}

/// RMS and max distance between detected and true corners, allowing the half-turn
/// relabelling of a symmetric board.
pub fn corner_error(detected: &[[f64; 2]], truth: &[[f64; 2]]) -> (f64, f64) {
    let d = |order: &mut dyn Iterator<Item = &[f64; 2]>| {
        let e: Vec<f64> = detected
            .iter()
            .zip(order)
            .map(|(p, q)| (p[0] - q[0]).hypot(p[1] - q[1]))
            .collect();
        let rms = (e.iter().map(|x| x * x).sum::<f64>() / e.len() as f64).sqrt();
        (rms, e.iter().cloned().fold(0.0, f64::max))
    };
    let a = d(&mut truth.iter());
    let b = d(&mut truth.iter().rev());
    if a.0 <= b.0 {
        a
    } else {
        b
    }
}

/// Corner error (rms, max) against the truth in every target image of `sim`, the corners found
/// with `opts`, in frames flat-fielded by the session's flat frames if `flat` (and there are
/// any). Panics where the board is not found.
pub fn detected_corner_errors(
    sim: &SimData,
    opts: &calib::CornerOptions,
    flat: bool,
) -> Vec<(f64, f64)> {
    let ff = (flat && !sim.inputs.flat_frames.is_empty())
        .then(|| calib::FlatField::estimate(&sim.inputs.flat_frames).unwrap());
    sim.inputs
        .target_frames
        .iter()
        .zip(&sim.true_corners)
        .enumerate()
        .map(|(i, (f, t))| {
            let found =
                calib::detect_board_flat(f, ff.as_ref(), &sim.inputs.board, opts, i).unwrap();
            corner_error(&found, t)
        })
        .collect()
}

/// Root mean square of per-image rms errors of equally many corners each.
pub fn pooled_rms(errors: &[(f64, f64)]) -> f64 {
    (errors.iter().map(|e| e.0 * e.0).sum::<f64>() / errors.len().max(1) as f64).sqrt()
}
