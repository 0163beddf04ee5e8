//! Binning's rays through gantry-hal's rig geometry with the full Brown–Conrady lens: every
//! pixel's ray projects back onto that pixel, and the tangential terms move the rays.

use binning::RigGeometry;
use gantry_hal::{CameraIntrinsics, CameraPose, LampCircle, SphereGeometry};
use nalgebra::Vector3;

fn rig(p1: f64, p2: f64, k3: f64) -> gantry_hal::RigGeometry {
    gantry_hal::RigGeometry {
        camera: CameraIntrinsics {
            width: 640,
            height: 480,
            fx: 536.0,
            fy: 536.0,
            cx: 342.4,
            cy: 235.5,
            k1: -0.265,
            k2: -0.047,
            p1,
            p2,
            k3,
        },
        pose: CameraPose::look_at([0.0, -1.0, 0.0], [0.0, 0.0, 0.0], 0.0),
        lamp: LampCircle {
            centre: [0.0; 3],
            normal: [0.0, 0.0, 1.0],
            radius: 0.5,
            reference: [0.0, 1.0, 0.0],
        },
        sphere: SphereGeometry {
            centre: [0.0; 3],
            radius: 0.0254,
        },
    }
}

#[test]
fn rays_project_back_onto_their_pixels_with_tangential_distortion() {
    let g = rig(0.0018, -0.0003, 0.25);
    g.validate().unwrap();
    assert_eq!(RigGeometry::sensor_size(&g), (640, 480));
    for &(u, v) in &[(0.0, 0.0), (320.0, 240.0), (639.0, 10.0), (17.0, 470.0)] {
        let (o, d) = RigGeometry::pixel_ray(&g, u, v);
        let p = RigGeometry::project(&g, &(o + 0.8 * d)).unwrap();
        assert!(
            (p[0] - u).abs() < 1e-8 && (p[1] - v).abs() < 1e-8,
            "{u} {v} {p:?}"
        );
    }
    // The decentring terms change where a corner pixel looks.
    let (_, d0) = RigGeometry::pixel_ray(&rig(0.0, 0.0, 0.25), 0.0, 0.0);
    let (_, d1) = RigGeometry::pixel_ray(&g, 0.0, 0.0);
    assert!(d0.angle(&d1) > 1e-4, "{}", d0.angle(&d1));
    let (c, r) = RigGeometry::sphere(&g);
    assert_eq!((c, r), (Vector3::zeros(), 0.0254));
}
