//! Scene set-ups for the thesis' figure types: a sphere under a point light, a teapot under
//! an environment map (or a point light), and a strip of spheres along a path of materials.

use crate::envmap::EnvironmentMap;
use crate::error::{RenderError, Result};
use crate::material::SurfaceMaterial;
use crate::mesh::{utah_teapot_wrapped, Mesh, Transform};
use crate::scene::{Camera, PointLight, Scene, SceneBuilder};
use brdf::Vec3;
use std::f64::consts::PI;

/// Point-light intensity that gives irradiance π (radiance 1 off a white Lambertian surface
/// facing the light) at distance `d`.
fn unit_intensity(d: f64) -> [f64; 3] {
    [PI * d * d; 3]
}

/// A unit sphere at the origin seen from +z under one point light (upper left, behind the
/// camera), black background. Render with [`crate::Integrator::Direct`] (thesis A.1) or path
/// tracing. Irradiance at the sphere is π, so a white Lambertian would reach radiance 1.
pub fn sphere_scene(material: SurfaceMaterial, width: usize, height: usize) -> Result<Scene> {
    let camera = Camera {
        position: Vec3::new(0.0, 0.0, 4.0),
        look_at: Vec3::zeros(),
        up: Vec3::y(),
        fov_degrees: 32.0,
        width,
        height,
    };
    let mut b = SceneBuilder::new(camera);
    let m = b.add_material(material);
    b.add_sphere(Vec3::zeros(), 1.0, m)?;
    let light = Vec3::new(-4.0, 4.0, 6.0);
    b.add_point_light(PointLight {
        position: light,
        intensity: unit_intensity(light.norm() - 1.0),
    })?;
    b.build()
}

/// The point the teapot figures' camera looks at ([`teapot_camera`]), about the middle of
/// the teapot, and the point the point light's intensity is scaled for.
pub const TEAPOT_LOOK_AT: [f64; 3] = [0.0, 0.75, 0.0];

/// Position of the point light of [`teapot_point_scene`]: upper left, in front of the teapot
/// (behind the camera's left shoulder).
pub const TEAPOT_POINT_LIGHT_POSITION: [f64; 3] = [-3.5, 6.0, 5.5];

/// The camera of the teapot figures: at (0, 2.6, 6.5) looking at [`TEAPOT_LOOK_AT`], y up,
/// 30° vertical field of view.
pub fn teapot_camera(width: usize, height: usize) -> Camera {
    Camera {
        position: Vec3::new(0.0, 2.6, 6.5),
        look_at: Vec3::from(TEAPOT_LOOK_AT),
        up: Vec3::y(),
        fov_degrees: 30.0,
        width,
        height,
    }
}

/// The teapot of the teapot figures, in world space: [`utah_teapot_wrapped`] tessellated with
/// 12 × 12 quads per patch, scaled by 0.5 (1.575 tall, standing on y = 0), turned −30° about
/// +y and moved by (−0.1, 0, 0). Normals are per vertex and turned with it; texture
/// coordinates are those of [`utah_teapot_wrapped`] (u around the teapot, v down it). Every
/// teapot figure renders this mesh, so another renderer given it sees the same geometry.
pub fn figure_teapot_mesh() -> Mesh {
    let t = Transform {
        scale: 0.5,
        rotate_y_degrees: -30.0,
        translate: Vec3::new(-0.1, 0.0, 0.0),
    };
    utah_teapot_wrapped(12).transformed(&t)
}

/// The Utah teapot ([`figure_teapot_mesh`]) made of `material`, seen by [`teapot_camera`], lit
/// by `environment` (the procedural probe when `None`), optionally standing on a ground plane.
pub fn teapot_scene(
    material: SurfaceMaterial,
    environment: Option<EnvironmentMap>,
    ground: Option<SurfaceMaterial>,
    width: usize,
    height: usize,
) -> Result<Scene> {
    let mut b = SceneBuilder::new(teapot_camera(width, height));
    let m = b.add_material(material);
    b.add_mesh(&figure_teapot_mesh(), &Transform::default(), m)?;
    if let Some(g) = ground {
        let gm = b.add_material(g);
        b.add_ground(0.0, 40.0, [0.0, 0.0], gm)?;
    }
    let env = match environment {
        Some(e) => e,
        None => EnvironmentMap::procedural_probe(512, 256, 1)?,
    };
    b.set_environment(env);
    b.build()
}

/// The point light of [`teapot_point_scene`]: at [`TEAPOT_POINT_LIGHT_POSITION`], with the
/// intensity `π d²` (d = its distance to [`TEAPOT_LOOK_AT`], √70.0625 ≈ 8.37, so about 220.1
/// W/sr per channel) that gives irradiance π at that distance: a white Lambertian surface
/// facing the light there reaches radiance 1, as in [`sphere_scene`].
pub fn teapot_point_light() -> PointLight {
    let position = Vec3::from(TEAPOT_POINT_LIGHT_POSITION);
    PointLight {
        position,
        intensity: unit_intensity((position - Vec3::from(TEAPOT_LOOK_AT)).norm()),
    }
}

/// The teapot figure for direct-lighting comparisons: [`figure_teapot_mesh`] made of
/// `material`, seen by [`teapot_camera`], lit by [`teapot_point_light`] alone, black
/// background, no ground. Render with [`crate::Integrator::Direct`] (thesis A.1).
pub fn teapot_point_scene(material: SurfaceMaterial, width: usize, height: usize) -> Result<Scene> {
    let mut b = SceneBuilder::new(teapot_camera(width, height));
    let m = b.add_material(material);
    b.add_mesh(&figure_teapot_mesh(), &Transform::default(), m)?;
    b.add_point_light(teapot_point_light())?;
    b.build()
}

/// A row of unit spheres, one per material (left to right), under a shared distant point
/// light; each sphere gets a `sphere_pixels` square of the image.
pub fn strip_scene(materials: Vec<SurfaceMaterial>, sphere_pixels: usize) -> Result<Scene> {
    let n = materials.len();
    if n == 0 {
        return Err(RenderError::InvalidArgument(
            "strip of zero materials".into(),
        ));
    }
    let spacing = 2.4;
    let distance = 60.0;
    let width_units = spacing * n as f64;
    let cx = (n as f64 - 1.0) * spacing * 0.5;
    let camera = Camera {
        position: Vec3::new(cx, 0.0, distance),
        look_at: Vec3::new(cx, 0.0, 0.0),
        up: Vec3::y(),
        fov_degrees: 2.0 * (spacing * 0.5 / distance).atan().to_degrees(),
        width: sphere_pixels * n,
        height: sphere_pixels,
    };
    let _ = width_units;
    let mut b = SceneBuilder::new(camera);
    for (i, m) in materials.into_iter().enumerate() {
        let id = b.add_material(m);
        b.add_sphere(Vec3::new(i as f64 * spacing, 0.0, 0.0), 1.0, id)?;
    }
    let light = Vec3::new(cx - 400.0, 400.0, 600.0);
    b.add_point_light(PointLight {
        position: light,
        intensity: unit_intensity((light - Vec3::new(cx, 0.0, 0.0)).norm()),
    })?;
    b.build()
}

/// Materials for a strip of truncated linear-model reconstructions: for each `k` in `ks`, the
/// material with only the first `k` of `coefficients` (clamped to the basis size), i.e. the
/// projection onto the first `k` components (the thesis's 5, 10, 20, 30, 45, 60, all series).
pub fn truncation_strip(
    basis: &std::sync::Arc<crate::material::LinearBasis>,
    coefficients: &[f64],
    ks: &[usize],
) -> Result<Vec<SurfaceMaterial>> {
    ks.iter()
        .map(|&k| {
            let k = k.min(coefficients.len()).min(basis.components());
            let brdf = crate::material::BasisBrdf::new(
                basis.clone(),
                &coefficients[..k],
                &format!("k={k}"),
            )?;
            Ok(SurfaceMaterial::Single(crate::material::Material::new(
                std::sync::Arc::new(brdf),
            )))
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::material::{BasisGrid, LinearBasis, SurfaceMaterial};
    use brdf::HalfDiff;
    use std::sync::Arc;

    #[test]
    fn truncation_strip_uses_the_first_k_components() {
        let grid = BasisGrid {
            theta_h: 2,
            theta_d: 2,
            phi_d: 2,
        };
        let n = 3 * grid.bins();
        let comps: Vec<Vec<f32>> = (0..3).map(|j| vec![(j + 1) as f32 * 0.1; n]).collect();
        let basis = Arc::new(LinearBasis::new(grid, &vec![0.0; n], &comps, 0.0).unwrap());
        let mats = truncation_strip(&basis, &[1.0, 1.0, 1.0], &[0, 1, 2, 60]).unwrap();
        let hd = HalfDiff::isotropic(0.1, 0.1, 0.1);
        let values: Vec<f64> = mats
            .iter()
            .map(|m| match m {
                SurfaceMaterial::Single(m) => m.brdf.eval_half_diff(&hd)[0],
                SurfaceMaterial::Blend { .. } | SurfaceMaterial::Varying { .. } => {
                    unreachable!("the strip is of single materials")
                }
            })
            .collect();
        // exp(0), exp(0.1), exp(0.1 + 0.2), exp(0.6) (k clamped to 3)
        for (v, want) in values.iter().zip([0.0f64, 0.1, 0.3, 0.6]) {
            assert!((v - want.exp()).abs() < 1e-6, "{values:?}");
        }
        let scene = strip_scene(mats, 8).unwrap();
        assert_eq!(scene.camera.width, 32);
    }
}
