//! Direct illumination (light sampling only) and one-bounce path tracing (BRDF sampling only)
//! are independent estimators of the same quantity: they must agree within their noise.

use brdf::Vec3;
use render::SpecResolver;
use render::*;
use std::sync::Arc;

fn scene() -> Scene {
    let camera = Camera {
        position: Vec3::new(0.0, 1.5, 5.0),
        look_at: Vec3::new(0.0, 0.7, 0.0),
        up: Vec3::y(),
        fov_degrees: 35.0,
        width: 32,
        height: 24,
    };
    let mut b = SceneBuilder::new(camera);
    let glossy = SpecResolver.spec("ward:kd=0.3,ks=0.25,alpha=0.2").unwrap();
    let res = ImportanceResolution {
        theta_r: 16,
        theta_i: 32,
        phi_diff: 64,
        supersample: 2,
    };
    let g = b.add_material(Material::with_importance(glossy, res));
    let d = b.add_material(Material::new(Arc::new(Lambert {
        kd: [0.5, 0.4, 0.3],
    })));
    b.add_sphere(Vec3::new(0.0, 0.8, 0.0), 0.8, g).unwrap();
    b.add_ground(0.0, 20.0, [0.0, 0.0], d).unwrap();
    b.add_area_light(AreaLight {
        corner: Vec3::new(-1.5, 3.0, -1.0),
        // edge_u × edge_v points down (−y): the light faces the scene
        edge_u: Vec3::new(3.0, 0.0, 0.0),
        edge_v: Vec3::new(0.0, 0.0, 2.0),
        radiance: [10.0, 10.0, 10.0],
    })
    .unwrap();
    b.set_environment(
        EnvironmentMap::procedural_probe(64, 32, 2)
            .unwrap()
            .with_scale(0.02),
    );
    b.build().unwrap()
}

/// Mean of one channel over an `s × s` block and the variance of that mean.
fn block_stats(out: &RenderOutput, x0: usize, y0: usize, s: usize, c: usize) -> (f64, f64) {
    let mut m = 0.0;
    let mut v = 0.0;
    let n = (s * s) as f64;
    for y in y0..y0 + s {
        for x in x0..x0 + s {
            m += out.image.get(x, y)[c] as f64;
            v += out.variance.get(x, y)[c] as f64;
        }
    }
    (m / n, v / (n * n))
}

/// Largest block z-score between two renders (all channels).
fn worst_z(a: &RenderOutput, b: &RenderOutput, label: &str) -> f64 {
    let mut worst: f64 = 0.0;
    for by in 0..3 {
        for bx in 0..4 {
            for c in 0..3 {
                let (ma, va) = block_stats(a, bx * 8, by * 8, 8, c);
                let (mb, vb) = block_stats(b, bx * 8, by * 8, 8, c);
                let z = (ma - mb).abs() / (va + vb).sqrt().max(1e-9);
                assert!(
                    z < 5.0,
                    "{label}: block ({bx},{by}) ch{c}: {ma:.4} vs {mb:.4}, z = {z:.2}"
                );
                worst = worst.max(z);
            }
        }
    }
    worst
}

#[test]
fn direct_lighting_agrees_with_one_bounce_path_tracing() {
    let scene = scene();
    let direct = RenderOptions {
        spp: 16,
        seed: 1,
        integrator: Integrator::Direct,
        mis: false,
        light_samples: 2,
        ..Default::default()
    };
    let one_bounce = RenderOptions {
        spp: 256,
        seed: 2,
        integrator: Integrator::PathTracing,
        max_depth: 1,
        next_event: false,
        ..Default::default()
    };
    let a = render_with_variance(&scene, &direct).unwrap();
    let b = render_with_variance(&scene, &one_bounce).unwrap();
    // the area light must dominate for the comparison to mean something
    let lit = (0..12)
        .map(|i| block_stats(&a, (i % 4) * 8, (i / 4) * 8, 8, 1).0)
        .filter(|&m| m > 0.15)
        .count();
    assert!(lit >= 6, "only {lit} blocks lit");
    worst_z(&a, &b, "light sampling vs BRDF sampling");
    // MIS combines both strategies and must agree too
    let mis = RenderOptions {
        mis: true,
        seed: 5,
        ..direct
    };
    let c = render_with_variance(&scene, &mis).unwrap();
    worst_z(&a, &c, "light sampling vs MIS");
}

#[test]
fn rendering_is_reproducible_from_the_seed() {
    let scene = scene();
    let o = RenderOptions {
        spp: 2,
        seed: 9,
        max_depth: 3,
        ..Default::default()
    };
    let a = render_scene(&scene, &o).unwrap();
    let b = render_scene(
        &scene,
        &RenderOptions {
            tile_size: 7,
            ..o.clone()
        },
    )
    .unwrap();
    let c = render_scene(&scene, &o).unwrap();
    let d = render_scene(&scene, &RenderOptions { seed: 10, ..o }).unwrap();
    assert_eq!(a, c);
    assert_ne!(a, d);
    // tile size changes the streams but not the expectation: same size, finite
    assert_eq!(a.width(), b.width());
    assert!(b.pixels().iter().flatten().all(|v| v.is_finite()));
}
