//! White furnace: albedo-1 Lambertian surfaces under a uniform unit environment reflect
//! radiance exactly 1, whatever the geometry and the sampling strategy.

use brdf::{Brdf, Vec3};
use render::*;
use std::sync::Arc;

/// The white Lambertian with importance tables; importance sampling uses Lambert's own
/// (cosine) sampler.
fn white() -> Material {
    white_from(Arc::new(Lambert { kd: [1.0; 3] }))
}

/// The white Lambertian tabulated on the MERL grid: a table has no sampler of its own, so
/// importance sampling uses the tables (thesis A.2.4).
fn white_table() -> Material {
    let table = brdf::MerlTable::tabulate(&Lambert { kd: [1.0; 3] });
    assert!(!table.has_importance_sampler());
    white_from(Arc::new(table))
}

fn white_from(brdf: Arc<dyn Brdf>) -> Material {
    Material::with_importance(
        brdf,
        ImportanceResolution {
            theta_r: 8,
            theta_i: 16,
            phi_diff: 32,
            supersample: 1,
        },
    )
}

fn camera(w: usize, h: usize, position: Vec3, look_at: Vec3) -> Camera {
    Camera {
        position,
        look_at,
        up: Vec3::y(),
        fov_degrees: 30.0,
        width: w,
        height: h,
    }
}

/// Mean of the image and its standard error (pixels are independent).
fn mean_and_error(out: &RenderOutput) -> ([f64; 3], [f64; 3]) {
    let n = out.image.pixels().len() as f64;
    let mut m = [0.0; 3];
    let mut v = [0.0; 3];
    for (p, q) in out.image.pixels().iter().zip(out.variance.pixels()) {
        for c in 0..3 {
            m[c] += p[c] as f64 / n;
            v[c] += q[c] as f64 / (n * n);
        }
    }
    (m, v.map(f64::sqrt))
}

#[test]
fn furnace_white_lambert_sphere_renders_radiance_one() {
    for (material, sampling, mis) in [
        (white(), BsdfSampling::Cosine, true),
        (white(), BsdfSampling::Uniform, true),
        (
            white(),
            BsdfSampling::Importance(PhiSampling::Inversion),
            true,
        ),
        (
            white_table(),
            BsdfSampling::Importance(PhiSampling::Inversion),
            true,
        ),
        (
            white_table(),
            BsdfSampling::Importance(PhiSampling::Rejection),
            false,
        ),
    ] {
        let mut b = SceneBuilder::new(camera(24, 24, Vec3::new(0.0, 0.0, 4.0), Vec3::zeros()));
        let m = b.add_material(material);
        b.add_sphere(Vec3::zeros(), 1.0, m).unwrap();
        b.set_environment(EnvironmentMap::constant([1.0; 3]).unwrap());
        let scene = b.build().unwrap();
        let opts = RenderOptions {
            spp: 16,
            seed: 3,
            bsdf_sampling: sampling,
            mis,
            max_depth: 16,
            ..Default::default()
        };
        let out = render_with_variance(&scene, &opts).unwrap();
        assert_eq!(out.dropped, 0);
        let (m, se) = mean_and_error(&out);
        for c in 0..3 {
            assert!(
                (m[c] - 1.0).abs() < 4.0 * se[c] + 1e-6 && (m[c] - 1.0).abs() < 0.01,
                "{sampling:?}: mean {m:?} ± {se:?}"
            );
        }
        // every pixel (sphere and background) is 1 within the noise; the pooled variance is
        // used because 16-sample variance estimates of a skewed estimator are unreliable
        let vars: Vec<f64> = out
            .variance
            .pixels()
            .iter()
            .map(|v| v[0] as f64)
            .filter(|&v| v > 0.0)
            .collect();
        let pooled = (vars.iter().sum::<f64>() / vars.len().max(1) as f64).sqrt();
        for (i, p) in out.image.pixels().iter().enumerate() {
            assert!(
                (p[0] as f64 - 1.0).abs() < 6.0 * pooled + 1e-5,
                "{sampling:?} pixel {i}: {p:?}, pooled sd {pooled}"
            );
        }
    }
}

#[test]
fn furnace_holds_with_interreflections_teapot_on_ground() {
    let mut b = SceneBuilder::new(camera(
        32,
        24,
        Vec3::new(0.0, 2.0, 6.0),
        Vec3::new(0.0, 0.6, 0.0),
    ));
    let m = b.add_material(white());
    b.add_mesh(
        &utah_teapot(4),
        &Transform {
            scale: 0.5,
            ..Default::default()
        },
        m,
    )
    .unwrap();
    b.add_ground(0.0, 30.0, [0.0, 0.0], m).unwrap();
    b.set_environment(EnvironmentMap::constant([1.0; 3]).unwrap());
    let scene = b.build().unwrap();
    let opts = RenderOptions {
        spp: 8,
        seed: 11,
        max_depth: 64,
        ..Default::default()
    };
    let out = render_with_variance(&scene, &opts).unwrap();
    let (m, se) = mean_and_error(&out);
    for c in 0..3 {
        assert!(
            (m[c] - 1.0).abs() < 4.0 * se[c] + 1e-6 && (m[c] - 1.0).abs() < 0.02,
            "mean {m:?} ± {se:?}"
        );
    }
}

#[test]
fn grey_furnace_scales_with_albedo() {
    // albedo 0.5 sphere: single bounce on a convex object reflects exactly 0.5
    let mut b = SceneBuilder::new(camera(16, 16, Vec3::new(0.0, 0.0, 3.0), Vec3::zeros()));
    let m = b.add_material(Material::new(Arc::new(Lambert {
        kd: [0.5, 0.25, 1.0],
    })));
    b.add_sphere(Vec3::zeros(), 1.0, m).unwrap();
    b.set_environment(EnvironmentMap::constant([1.0; 3]).unwrap());
    let scene = b.build().unwrap();
    let out = render_with_variance(
        &scene,
        &RenderOptions {
            spp: 32,
            ..Default::default()
        },
    )
    .unwrap();
    // centre pixel is on the sphere
    let p = out.image.get(8, 8);
    let v = out.variance.get(8, 8);
    for (c, want) in [0.5, 0.25, 1.0].into_iter().enumerate() {
        assert!(
            (p[c] as f64 - want).abs() < 5.0 * (v[c] as f64).sqrt() + 1e-6,
            "{p:?} vs {want}"
        );
    }
}
