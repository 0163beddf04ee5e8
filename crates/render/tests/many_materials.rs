//! The many-materials shader: 10,000 distinct materials, each k = 45 coefficients against one
//! shared log-space basis, render in less memory than the basis itself.

use brdf::{Brdf, HalfDiff, Vec3};
use rand::{Rng, SeedableRng};
use render::*;
use std::sync::Arc;

fn basis(grid: BasisGrid, k: usize) -> LinearBasis {
    let bins = grid.bins();
    let mut mean = vec![0f32; 3 * bins];
    let mut comps = vec![vec![0f32; 3 * bins]; k];
    for i in 0..grid.theta_h {
        for j in 0..grid.theta_d {
            for l in 0..grid.phi_d {
                let b = l + grid.phi_d * (j + grid.theta_d * i);
                let (th, td, pd) = grid.angles(i, j, l);
                for c in 0..3 {
                    // log of a diffuse term plus a specular lobe in θh
                    let f = 0.1 + 0.05 * c as f64 + 5.0 * (-th * th / 0.01).exp();
                    mean[c * bins + b] = f.ln() as f32;
                    for (q, comp) in comps.iter_mut().enumerate() {
                        let w = (q + 1) as f64;
                        comp[c * bins + b] = (0.1
                            * ((w * th * 3.0).cos() + (w * td).sin() * pd.cos() + 0.2 * c as f64))
                            as f32;
                    }
                }
            }
        }
    }
    LinearBasis::new(grid, &mean, &comps, 0.0).unwrap()
}

#[test]
fn ten_thousand_materials_render_within_one_basis_memory() {
    let grid = BasisGrid {
        theta_h: 30,
        theta_d: 30,
        phi_d: 60,
    };
    let k = 45;
    let basis = Arc::new(basis(grid, k));
    let camera = Camera {
        position: Vec3::new(50.0, 160.0, 50.01),
        look_at: Vec3::new(50.0, 0.0, 50.0),
        up: Vec3::z(),
        fov_degrees: 36.0,
        width: 160,
        height: 160,
    };
    let mut b = SceneBuilder::new(camera);
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(4);
    let mut own = 0usize;
    for i in 0..100 {
        for j in 0..100 {
            let coeffs: Vec<f64> = (0..k).map(|_| rng.gen_range(-1.5..1.5)).collect();
            let m = BasisBrdf::new(basis.clone(), &coeffs, "m").unwrap();
            own += m.own_memory_bytes();
            let id = b.add_material(Material::new(Arc::new(m)));
            b.add_sphere(Vec3::new(i as f64 + 0.5, 0.0, j as f64 + 0.5), 0.45, id)
                .unwrap();
        }
    }
    b.add_point_light(PointLight {
        position: Vec3::new(30.0, 300.0, 80.0),
        intensity: [1e5; 3],
    })
    .unwrap();
    let scene = b.build().unwrap();
    assert_eq!(scene.materials.len(), 10_000);
    // each material owns its 45 floats; all share one basis
    assert!(
        own < basis.memory_bytes(),
        "{own} B of coefficients vs {} B basis",
        basis.memory_bytes()
    );
    assert!(own <= 10_000 * (45 * 4 + 1));
    let img = render_scene(
        &scene,
        &RenderOptions {
            spp: 1,
            integrator: Integrator::Direct,
            ..Default::default()
        },
    )
    .unwrap();
    // distinct materials give distinct colours: many different pixel values on the spheres
    let mut values: Vec<[u32; 3]> = img
        .pixels()
        .iter()
        .filter(|p| p[0] > 0.0)
        .map(|p| p.map(f32::to_bits))
        .collect();
    let lit = values.len();
    values.sort();
    values.dedup();
    assert!(
        lit > 10_000 && values.len() > 5_000,
        "{lit} lit pixels, {} distinct",
        values.len()
    );
}

#[test]
fn basis_material_matches_direct_evaluation_in_a_render() {
    // a sphere under a point light seen head-on: the centre pixel is f(n, n) · I / d² · cos
    let grid = BasisGrid {
        theta_h: 2,
        theta_d: 12,
        phi_d: 24,
    };
    let basis = Arc::new(basis(grid, 5));
    let m = BasisBrdf::new(basis, &[0.3, -0.2, 0.1, 0.0, 0.5], "m").unwrap();
    let expected_f = m.eval_half_diff(&HalfDiff::isotropic(0.0, 0.0, 0.0));
    let camera = Camera {
        position: Vec3::new(0.0, 0.0, 10.0),
        look_at: Vec3::zeros(),
        up: Vec3::y(),
        fov_degrees: 5.0,
        width: 9,
        height: 9,
    };
    let mut b = SceneBuilder::new(camera);
    let id = b.add_material(Material::new(Arc::new(m)));
    b.add_sphere(Vec3::zeros(), 1.0, id).unwrap();
    b.add_point_light(PointLight {
        position: Vec3::new(0.0, 0.0, 10.0),
        intensity: [81.0; 3],
    })
    .unwrap();
    let scene = b.build().unwrap();
    let opts = RenderOptions {
        spp: 1,
        integrator: Integrator::Direct,
        ..Default::default()
    };
    let img = render_scene(&scene, &opts).unwrap();
    let p = img.get(4, 4);
    for c in 0..3 {
        // within the centre pixel θh < 3° stays in the first bin; irradiance 81 / 9² · cos ≈ 1
        let want = expected_f[c];
        assert!(
            (p[c] as f64 - want).abs() < 0.01 * want,
            "{p:?} vs {expected_f:?}"
        );
    }
}
