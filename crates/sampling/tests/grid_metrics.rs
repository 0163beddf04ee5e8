mod common;

use brdf::analytic::Lambert;
use sampling::metrics::{image_rms_relative, log_rms_relative, render_sphere, sphere_lights};
use sampling::{GridTable, SampleGrid};

#[test]
fn nearest_grid_point_of_grid_angles_is_itself() {
    for grid in [
        SampleGrid::new(1, 1, 1).unwrap(),
        SampleGrid::new(3, 3, 6).unwrap(),
        SampleGrid::new(7, 4, 13).unwrap(),
    ] {
        let step = if grid.len() > 100_000 { 97 } else { 1 };
        for i in (0..grid.len()).step_by(step) {
            let (th, td, pd) = grid.angles(i);
            assert_eq!(grid.nearest(th, td, pd), i);
            // φd and φd + π are the same configuration.
            assert_eq!(grid.nearest(th, td, pd + std::f64::consts::PI), i);
        }
    }
    assert!(SampleGrid::new(0, 1, 1).is_err());
}

#[test]
fn merl_round_trip_on_the_full_grid() {
    let mat = Lambert {
        kd: [0.1, 0.2, 0.3],
    };
    let grid = common::small_grid();
    let t = GridTable::tabulate(&mat, grid);
    let merl = t.to_merl().unwrap();
    assert_eq!(GridTable::from_merl(&merl, grid), t);
}

#[test]
fn log_metric_is_zero_for_identity_and_one_for_black() {
    let (_, tables) = common::corpus(common::small_grid());
    let t = &tables[4];
    assert_eq!(log_rms_relative(t, t).unwrap(), 0.0);
    let black = GridTable::new(t.grid, vec![0.0; t.values.len()]).unwrap();
    assert!((log_rms_relative(t, &black).unwrap() - 1.0).abs() < 1e-12);
    let other = GridTable::new(
        SampleGrid::new(5, 5, 5).unwrap(),
        vec![0.0; 3 * 18 * 18 * 36],
    );
    assert!(log_rms_relative(t, &other.unwrap()).is_err());
}

#[test]
fn sphere_image_matches_the_lambert_closed_form_and_scales_linearly() {
    let kd = [0.2, 0.5, 0.8];
    let t = GridTable::tabulate(&Lambert { kd }, common::small_grid());
    let size = 33;
    let img = render_sphere(&t, size);
    // Centre pixel: normal ≈ +z, radiance = kd/π Σ max(l·n, 0).
    let centre = img[(size / 2) * size + size / 2];
    let x = (16.5 / 33.0) * 2.0 - 1.0;
    let n = brdf::Vec3::new(x, -x, (1.0 - 2.0 * x * x).sqrt());
    let cos_sum: f64 = sphere_lights().iter().map(|l| l.dot(&n).max(0.0)).sum();
    for c in 0..3 {
        let expect = kd[c] / std::f64::consts::PI * cos_sum;
        assert!((centre[c] - expect).abs() < 1e-9 * expect.max(1.0), "{c}");
    }
    // Off-sphere corner is black.
    assert_eq!(img[0], [0.0; 3]);
    let scaled = GridTable::new(t.grid, t.values.iter().map(|v| 1.25 * v).collect()).unwrap();
    let e = image_rms_relative(&t, &scaled, size).unwrap();
    assert!((e - 0.25).abs() < 1e-12, "{e}");
}
