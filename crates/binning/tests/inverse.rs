//! The inverse mapping (thesis §3.5) on an ideal rig written here: a distortion-free pinhole
//! camera, a point lamp on a horizontal circle, and Bayer images rendered per pixel from an
//! analytic BRDF.

use binning::BinningError;
use binning::PositionSamples;
use binning::{bin_samples, BinningOptions};
use binning::{
    fill_table, solve_point, Configuration, Construction, InverseOptions, InversePosition,
    InverseTable, PositionChoice,
};
use binning::{ray_sphere, RigGeometry, SphereView, V3};
use binning::{ForwardOptions, Rates};
use brdf::{Brdf, HalfDiff};
use brdf::{MerlTable, BINS};
use proptest::prelude::*;

/// Pinhole camera at (0, −1, 0) looking along +y; lamp on a circle of radius 0.5 in the z = 0
/// plane, at angle 0 opposite the camera; sphere of radius 0.0254 at the origin.
struct PinholeRig {
    width: usize,
    height: usize,
    focal_px: f64,
}

const CAMERA: [f64; 3] = [0.0, -1.0, 0.0];
const LAMP_RADIUS: f64 = 0.5;
const SPHERE_RADIUS: f64 = 0.0254;
const K: [f64; 3] = [1.8e5, 2.6e5, 1.2e5];

impl PinholeRig {
    fn new() -> Self {
        Self {
            width: 160,
            height: 120,
            focal_px: 2600.0,
        }
    }
    fn centre_px(&self) -> (f64, f64) {
        (
            (self.width as f64 - 1.0) / 2.0,
            (self.height as f64 - 1.0) / 2.0,
        )
    }
}

impl RigGeometry for PinholeRig {
    fn sensor_size(&self) -> (usize, usize) {
        (self.width, self.height)
    }
    fn pixel_ray(&self, u: f64, v: f64) -> (V3, V3) {
        let (cx, cy) = self.centre_px();
        // Image columns run along +x, rows along −z.
        let d = V3::new((u - cx) / self.focal_px, 1.0, -(v - cy) / self.focal_px);
        (V3::from(CAMERA), d.normalize())
    }
    fn project(&self, p: &V3) -> Option<[f64; 2]> {
        let q = p - V3::from(CAMERA);
        if q.y <= 0.0 {
            return None;
        }
        let (cx, cy) = self.centre_px();
        Some([
            self.focal_px * q.x / q.y + cx,
            -self.focal_px * q.z / q.y + cy,
        ])
    }
    fn lamp_position(&self, angle_deg: f64) -> V3 {
        let a = angle_deg.to_radians();
        V3::new(LAMP_RADIUS * a.sin(), LAMP_RADIUS * a.cos(), 0.0)
    }
    fn sphere(&self) -> (V3, f64) {
        (V3::zeros(), SPHERE_RADIUS)
    }
}

/// RGGB mosaic.
fn bayer(x: usize, y: usize) -> usize {
    match (x % 2, y % 2) {
        (0, 0) => 0,
        (1, 1) => 2,
        _ => 1,
    }
}

/// The BRDF of `brdf` for world directions at a point with normal `n`.
fn eval_world(brdf: &dyn Brdf, n: &V3, to_lamp: &V3, to_camera: &V3) -> [f64; 3] {
    let t = n.cross(&V3::new(0.6, -0.3, 0.74)).normalize();
    let b = n.cross(&t);
    let local = |w: &V3| V3::new(w.dot(&t), w.dot(&b), w.dot(n));
    brdf.eval(&local(to_lamp), &local(to_camera))
}

/// Rates (DN/s) and valid flags of the sphere image with the lamp at `angle`, plus `ambient`.
fn render(rig: &PinholeRig, brdf: &dyn Brdf, angle: f64, ambient: f32) -> (Vec<f32>, Vec<bool>) {
    let (w, h) = (rig.width, rig.height);
    let mut rate = vec![0.0f32; w * h];
    let mut valid = vec![true; w * h];
    let lamp = rig.lamp_position(angle);
    for y in 0..h {
        for x in 0..w {
            let i = y * w + x;
            let (o, d) = rig.pixel_ray(x as f64, y as f64);
            let Some(t) = ray_sphere(&o, &d, &V3::zeros(), SPHERE_RADIUS) else {
                valid[i] = false;
                continue;
            };
            let p = o + d * t;
            let n = p / SPHERE_RADIUS;
            let l = lamp - p;
            let to_lamp = l.normalize();
            let cos_i = n.dot(&to_lamp);
            let c = bayer(x, y);
            rate[i] = ambient;
            if cos_i > 0.0 {
                let f = eval_world(brdf, &n, &to_lamp, &-d)[c];
                rate[i] += (K[c] * f * cos_i / l.norm_squared()) as f32;
            }
        }
    }
    (rate, valid)
}

fn angles(n: usize, last: f64) -> Vec<f64> {
    (0..n).map(|i| last * i as f64 / (n - 1) as f64).collect()
}

/// One simulated capture: the positions for the inverse mapping and the forward-binned table.
struct Capture {
    rig: PinholeRig,
    view: SphereView,
    positions: Vec<InversePosition>,
    forward: MerlTable,
}

fn capture(brdf: &dyn Brdf, angles: &[f64], ambient: f32) -> Capture {
    let rig = PinholeRig::new();
    let view = SphereView::new(&rig, bayer, 85.0);
    let mut positions = Vec::new();
    let mut forward = Vec::new();
    for (k, &a) in angles.iter().enumerate() {
        let (rate, valid) = render(&rig, brdf, a, ambient);
        let rates = Rates {
            rate: &rate,
            valid: &valid,
        };
        positions
            .push(InversePosition::new(&rig, &view, a, rates, &InverseOptions::default()).unwrap());
        let samples = binning::position_samples(
            &view,
            rates,
            &rig.lamp_position(a),
            &K,
            &ForwardOptions::default(),
        )
        .unwrap();
        forward.push(PositionSamples {
            position: k as u32,
            angle_deg: a,
            samples,
        });
    }
    let binned = bin_samples(forward.as_slice(), &BinningOptions::default()).unwrap();
    Capture {
        rig,
        view,
        positions,
        forward: binned.table,
    }
}

impl Capture {
    fn inverse(&self, opts: &InverseOptions) -> InverseTable {
        fill_table(&self.rig, &self.view, &self.positions, &K, opts).unwrap()
    }
}

/// |ln(measured / truth)| over keys valid in `measured` (and in `mask`, if given) with positive
/// truth, sorted.
fn log_errors(measured: &MerlTable, truth: &MerlTable, mask: Option<&MerlTable>) -> Vec<f64> {
    let mut e = Vec::new();
    for c in 0..3 {
        for b in 0..BINS {
            if !measured.is_valid(c, b) || mask.is_some_and(|m| !m.is_valid(c, b)) {
                continue;
            }
            let t = truth.get(c, b);
            if t > 0.0 {
                e.push((measured.get(c, b) / t).ln().abs());
            }
        }
    }
    e.sort_by(|a, b| a.total_cmp(b));
    e
}

fn quantile(e: &[f64], q: f64) -> f64 {
    e[((e.len() as f64 * q) as usize).min(e.len() - 1)]
}

#[test]
fn lambertian_sphere_maps_to_its_albedo_with_stray_light_removed() {
    let lambert = brdf::analytic::Lambert {
        kd: [0.55, 0.35, 0.15],
    };
    // Lamp angles where the shadowed side is in view, so the stray light can be estimated.
    let pos: Vec<f64> = angles(56, 100.0).iter().map(|a| a + 10.0).collect();
    let cap = capture(&lambert, &pos, 30.0);
    for construction in [Construction::Circles, Construction::HalfVector] {
        let inv = cap.inverse(&InverseOptions {
            construction,
            ..Default::default()
        });
        assert!(inv.coverage() > 0.05, "coverage {}", inv.coverage());
        let mut worst: f64 = 0.0;
        for c in 0..3 {
            let expect = lambert.kd[c] / std::f64::consts::PI;
            for b in 0..BINS {
                if inv.table.is_valid(c, b) {
                    worst = worst.max((inv.table.get(c, b) / expect - 1.0).abs());
                }
            }
        }
        // Bilinear interpolation of a smooth radiance field over 2-pixel lattice steps.
        assert!(
            worst < 2e-3,
            "{construction:?}: worst relative error {worst}"
        );
    }
}

#[test]
fn glossy_sphere_matches_the_true_table_better_than_forward_binning() {
    let ggx = brdf::analytic::Ggx {
        kd: [0.1, 0.08, 0.05],
        ks: [0.6; 3],
        alpha: 0.12,
        ior: 1.5,
    };
    let truth = MerlTable::tabulate(&ggx);
    let pos = angles(111, 165.0);
    let cap = capture(&ggx, &pos, 0.0);
    let fwd = &cap.forward;
    let inv = cap.inverse(&InverseOptions {
        construction: Construction::HalfVector,
        ..Default::default()
    });
    // Over the keys both methods cover.
    let e_inv = log_errors(&inv.table, &truth, Some(fwd));
    let e_fwd = log_errors(fwd, &truth, Some(&inv.table));
    assert!(e_inv.len() > 50_000, "{} keys", e_inv.len());
    let (mi, mf) = (quantile(&e_inv, 0.5), quantile(&e_fwd, 0.5));
    let (pi, pf) = (quantile(&e_inv, 0.9), quantile(&e_fwd, 0.9));
    assert!(mi < 0.01, "inverse median |log error| {mi}");
    assert!(mi < 0.5 * mf, "inverse median {mi} vs forward {mf}");
    assert!(pi < pf, "inverse p90 {pi} vs forward {pf}");
    // The thesis's circle construction with its nearest-position choice: θi and θr exact, the
    // discrete lamp angle goes into φdiff. Near the specular configuration the circles are
    // nearly tangent and that error is amplified into θh, so it does clearly worse at p90.
    let inv_c = cap.inverse(&InverseOptions {
        construction: Construction::Circles,
        choice: PositionChoice::Nearest,
        reciprocity: false,
        ..Default::default()
    });
    let e_c = log_errors(&inv_c.table, &truth, None);
    let (mc, pc) = (quantile(&e_c, 0.5), quantile(&e_c, 0.9));
    assert!(e_c.len() > 50_000, "{} keys", e_c.len());
    assert!(
        mc < 0.1 && pc > 5.0 * pi,
        "circles, nearest: median {mc}, p90 {pc}"
    );
}

/// A surface point facing both camera and lamp, from two unit-square coordinates.
fn point_on_sphere(s: f64, t: f64) -> V3 {
    let z = 0.9 * (2.0 * s - 1.0);
    let phi = -std::f64::consts::PI * t;
    let r = (1.0 - z * z).sqrt();
    V3::new(r * phi.cos(), r * phi.sin(), z) * SPHERE_RADIUS
}

/// Rusinkiewicz angles of the configuration seen at `p` with the lamp at `lamp`.
fn observed(p: &V3, lamp: &V3) -> (HalfDiff, V3, V3) {
    let n = p.normalize();
    let to_lamp = (lamp - p).normalize();
    let to_cam = (V3::from(CAMERA) - p).normalize();
    let (t, b) = binning::frame_from_normal(&n);
    let loc = |w: &V3| binning::to_local(w, &t, &b, &n);
    (
        HalfDiff::from_directions(&loc(&to_lamp), &loc(&to_cam)),
        to_lamp,
        to_cam,
    )
}

fn angle_between(a: &V3, b: &V3) -> f64 {
    a.dot(b).clamp(-1.0, 1.0).acos()
}

proptest! {
    // Seeded, so that every run tests the same cases.
    #![proptest_config(ProptestConfig {
        cases: 128,
        failure_persistence: None,
        rng_seed: proptest::test_runner::RngSeed::Fixed(20261122),
        ..ProptestConfig::default()
    })]

    /// The circle intersection returns points whose actual angles to the finite-distance lamp
    /// and camera are the requested θi and θr, on the requested side.
    #[test]
    fn circle_intersection_has_the_requested_angles(
        th in 0.0f64..1.3, td in 0.05f64..1.4, pd in 0.0f64..std::f64::consts::TAU,
        angle in 0.0f64..165.0,
    ) {
        let rig = PinholeRig::new();
        let lamp = rig.lamp_position(angle);
        let config = Configuration::from_half_diff(th, td, pd);
        let sol = solve_point(Construction::Circles, &config, &V3::zeros(), SPHERE_RADIUS,
            &lamp, &V3::from(CAMERA));
        if let Some(sp) = sol {
            let to_lamp = (lamp - sp.point).normalize();
            let to_cam = (V3::from(CAMERA) - sp.point).normalize();
            prop_assert!((sp.point.norm() - SPHERE_RADIUS).abs() < 1e-12);
            prop_assert!((sp.normal.dot(&to_lamp) - config.theta_i.cos()).abs() < 1e-10);
            prop_assert!((sp.normal.dot(&to_cam) - config.theta_o.cos()).abs() < 1e-10);
            prop_assert!((angle_between(&to_lamp, &to_cam) - sp.gamma).abs() < 1e-9);
            let side = sp.normal.dot(&to_lamp.cross(&to_cam));
            prop_assert!(config.handedness * side >= -1e-9, "side {side}");
        }
    }

    /// Round trip: the configuration observed at a surface point, requested for the same lamp,
    /// gives back that point with either construction.
    #[test]
    fn observed_configuration_solves_back_to_its_point(
        s in 0.0f64..1.0, t in 0.0f64..1.0, angle in 20.0f64..165.0,
    ) {
        let rig = PinholeRig::new();
        let lamp = rig.lamp_position(angle);
        let p = point_on_sphere(s, t);
        let (hd, to_lamp, to_cam) = observed(&p, &lamp);
        let n = p.normalize();
        prop_assume!(n.dot(&to_lamp) > 0.05 && n.dot(&to_cam) > 0.05 && hd.theta_h > 1e-3);
        let config = Configuration::from_half_diff(hd.theta_h, hd.theta_d, hd.phi_d);
        // The circles cross at an angle whose sine is |n · (l × v)| / (sin θi sin θo); near
        // tangency (the point near the plane through lamp and camera) their intersection is
        // ill-conditioned and the circle construction may find nothing. The half-vector
        // construction has no such case.
        let crossing = n.dot(&to_lamp.cross(&to_cam)).abs()
            / (config.theta_i.sin() * config.theta_o.sin());
        for construction in [Construction::Circles, Construction::HalfVector] {
            let sp = solve_point(construction, &config, &V3::zeros(), SPHERE_RADIUS, &lamp,
                &V3::from(CAMERA));
            if sp.is_none() && construction == Construction::Circles && crossing < 0.05 {
                continue;
            }
            let sp = sp.ok_or_else(|| TestCaseError::fail(format!("{construction:?}: none")))?;
            prop_assert!((sp.point - p).norm() < 1e-9 * SPHERE_RADIUS * 1e3,
                "{construction:?}: {} m away", (sp.point - p).norm());
            prop_assert!((sp.gamma - 2.0 * hd.theta_d).abs() < 1e-9);
        }
    }

    /// The half-vector construction keeps θh and φd exact at the finite-distance point.
    #[test]
    fn half_vector_point_has_the_requested_half_angles(
        th in 0.0f64..1.2, td in 0.1f64..1.3, pd in 0.0f64..std::f64::consts::TAU,
        angle in 10.0f64..165.0,
    ) {
        let rig = PinholeRig::new();
        let lamp = rig.lamp_position(angle);
        let config = Configuration::from_half_diff(th, td, pd);
        let sp = solve_point(Construction::HalfVector, &config, &V3::zeros(), SPHERE_RADIUS,
            &lamp, &V3::from(CAMERA)).ok_or_else(|| TestCaseError::fail("no point"))?;
        let (hd, _, _) = observed(&sp.point, &lamp);
        prop_assert!((hd.theta_h - th).abs() < 1e-7, "θh {} vs {th}", hd.theta_h);
        if th > 1e-3 {
            let dphi = (hd.phi_d - pd).rem_euclid(std::f64::consts::TAU);
            prop_assert!(dphi.min(std::f64::consts::TAU - dphi) < 1e-6, "φd {} vs {pd}", hd.phi_d);
        }
        prop_assert!((hd.theta_d - sp.gamma / 2.0).abs() < 1e-9);
    }
}

#[test]
fn bad_inputs_are_typed_errors() {
    let rig = PinholeRig::new();
    let opts = InverseOptions::default();
    let view = SphereView::new(&rig, bayer, 85.0);
    let lambert = brdf::analytic::Lambert { kd: [0.5; 3] };
    let (rate, valid) = render(&rig, &lambert, 90.0, 0.0);
    let rates = Rates {
        rate: &rate,
        valid: &valid,
    };
    let short = Rates {
        rate: &rate[1..],
        valid: &valid,
    };
    assert!(matches!(
        InversePosition::new(&rig, &view, 90.0, short, &opts),
        Err(BinningError::Dimensions(_))
    ));
    assert!(matches!(
        InversePosition::new(&rig, &view, f64::NAN, rates, &opts),
        Err(BinningError::Parameter(_))
    ));
    let pos = vec![InversePosition::new(&rig, &view, 90.0, rates, &opts).unwrap()];
    let err = |k: &[f64; 3], o: &InverseOptions, p: &[InversePosition]| {
        fill_table(&rig, &view, p, k, o).err()
    };
    assert!(matches!(
        err(&[1.0, 0.0, 1.0], &opts, &pos),
        Some(BinningError::Parameter(_))
    ));
    assert!(matches!(
        err(&[1.0, f64::NAN, 1.0], &opts, &pos),
        Some(BinningError::Parameter(_))
    ));
    assert!(matches!(
        err(&K, &opts, &[]),
        Some(BinningError::Parameter(_))
    ));
    for bad in [
        InverseOptions {
            max_incidence_deg: f64::NAN,
            ..Default::default()
        },
        InverseOptions {
            max_view_deg: 120.0,
            ..Default::default()
        },
        InverseOptions {
            max_bracket_deg: 0.0,
            ..Default::default()
        },
    ] {
        assert!(matches!(
            err(&K, &bad, &pos),
            Some(BinningError::Parameter(_))
        ));
    }
    // A position built for another view.
    let mut other = pos.clone();
    other[0].rate.pop();
    assert!(matches!(
        err(&K, &opts, &other),
        Some(BinningError::Dimensions(_))
    ));
    // A non-finite rate is only an invalid pixel, not an error.
    let mut nan_rate = rate.clone();
    nan_rate.iter_mut().step_by(7).for_each(|r| *r = f32::NAN);
    let p = InversePosition::new(
        &rig,
        &view,
        90.0,
        Rates {
            rate: &nan_rate,
            valid: &valid,
        },
        &opts,
    )
    .unwrap();
    assert!(p.rate.iter().any(|r| r.is_nan()));
}

/// A grazing, nearly specular configuration close to the plane through lamp and camera (found by
/// an unseeded property run): the circles of the thesis's construction are almost tangent there,
/// and the half-vector construction still finds the point.
#[test]
fn half_vector_construction_solves_where_the_circles_are_nearly_tangent() {
    let rig = PinholeRig::new();
    let lamp = rig.lamp_position(20.620832211977195);
    let p = point_on_sphere(0.5024311897842243, 0.0780978081770528);
    let (hd, to_lamp, to_cam) = observed(&p, &lamp);
    let n = p.normalize();
    let config = Configuration::from_half_diff(hd.theta_h, hd.theta_d, hd.phi_d);
    let crossing =
        n.dot(&to_lamp.cross(&to_cam)).abs() / (config.theta_i.sin() * config.theta_o.sin());
    assert!(crossing < 0.01, "crossing {crossing}");
    let sp = solve_point(
        Construction::HalfVector,
        &config,
        &V3::zeros(),
        SPHERE_RADIUS,
        &lamp,
        &V3::from(CAMERA),
    )
    .expect("half-vector solution");
    assert!(
        (sp.point - p).norm() < 1e-9,
        "{} m away",
        (sp.point - p).norm()
    );
}
