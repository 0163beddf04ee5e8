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
    figure_scene(
        &figure_teapot_mesh(),
        material,
        environment,
        ground,
        width,
        height,
    )
}

/// [`teapot_scene`] with another mesh in the teapot's place (one placed like it, such as
/// [`figure_bunny_mesh`]).
pub fn figure_scene(
    mesh: &Mesh,
    material: SurfaceMaterial,
    environment: Option<EnvironmentMap>,
    ground: Option<SurfaceMaterial>,
    width: usize,
    height: usize,
) -> Result<Scene> {
    let mut b = SceneBuilder::new(teapot_camera(width, height));
    let m = b.add_material(material);
    b.add_mesh(mesh, &Transform::default(), m)?;
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
    figure_point_scene(&figure_teapot_mesh(), material, width, height)
}

/// [`teapot_point_scene`] with another mesh in the teapot's place (one placed like it, such as
/// [`figure_bunny_mesh`]).
pub fn figure_point_scene(
    mesh: &Mesh,
    material: SurfaceMaterial,
    width: usize,
    height: usize,
) -> Result<Scene> {
    let mut b = SceneBuilder::new(teapot_camera(width, height));
    let m = b.add_material(material);
    b.add_mesh(mesh, &Transform::default(), m)?;
    b.add_point_light(teapot_point_light())?;
    b.build()
}

/// Where the shared data keeps the Stanford bunny (`BRDF_DATA_DIR`, see `brdf::data_dir`).
pub fn shared_bunny_path() -> std::path::PathBuf {
    brdf::data_dir().join("real/meshes/stanford-bunny.obj")
}

/// The Stanford bunny of the shared data ([`shared_bunny_path`]) placed by
/// [`figure_mesh_from_obj`]: [`BUNNY_HEIGHT`] tall (it is narrower than the teapot), turned
/// [`BUNNY_ROTATION_DEGREES`]: [`teapot_camera`] sees it in profile, facing left.
pub fn figure_bunny_mesh() -> Result<Mesh> {
    figure_mesh_from_obj(&shared_bunny_path(), BUNNY_HEIGHT, BUNNY_ROTATION_DEGREES)
}

/// The bunny's height in the figures.
pub const BUNNY_HEIGHT: f64 = 1.9;
/// The bunny's turn about +y in the figures, degrees.
pub const BUNNY_ROTATION_DEGREES: f64 = 0.0;

/// The Stanford bunny (or any OBJ mesh) placed where the teapot figures put the teapot, so
/// that [`teapot_camera`] and [`teapot_point_light`] frame and light it: scaled to `height`
/// (the figure teapot is 1.575 tall), standing on y = 0, centred on the vertical axis and
/// turned `rotate_y_degrees` about it. Normals are made smooth ([`Mesh::smooth_normals`]) and
/// texture coordinates cylindrical about that axis ([`Mesh::cylindrical_uvs`]: u around,
/// v down, as on the teapot), so the rust field of [`crate::rust_selector`] covers it too.
pub fn figure_mesh_from_obj(
    path: &std::path::Path,
    height: f64,
    rotate_y_degrees: f64,
) -> Result<Mesh> {
    if !(height > 0.0 && height.is_finite()) {
        return Err(RenderError::InvalidArgument(format!(
            "a figure mesh {height} tall"
        )));
    }
    let mesh = crate::mesh::read_obj(path)?;
    let (lo, hi) = mesh.bounds();
    let own = hi.y - lo.y;
    if own.is_nan() || own <= 0.0 {
        return Err(RenderError::InvalidArgument(format!(
            "{}: the mesh has no height",
            path.display()
        )));
    }
    // scale and turn about +y, then move the centre of the base (of the turned bounds) to
    // the origin
    let turned = mesh.transformed(&Transform {
        scale: height / own,
        rotate_y_degrees,
        translate: Vec3::zeros(),
    });
    let (lo, hi) = turned.bounds();
    let mut mesh = turned.transformed(&Transform {
        scale: 1.0,
        rotate_y_degrees: 0.0,
        translate: Vec3::new(-(lo.x + hi.x) * 0.5, -lo.y, -(lo.z + hi.z) * 0.5),
    });
    mesh.smooth_normals();
    mesh.cylindrical_uvs(0.0, 0.0);
    mesh.validate()?;
    Ok(mesh)
}

/// A grid of unit spheres, one per material, filled row by row from the top left: the
/// layout of the thesis's progressions (fig. 5-7: polished steel at the upper left, black
/// oxidized at the lower right) and of strips (one row). The spheres' centres are 2.4 apart
/// in the plane z = 0, seen head-on by a distant camera, and lit by one distant point light
/// at the upper left behind the camera; each sphere gets a `sphere_pixels` square.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct SphereGrid {
    /// Spheres per row.
    pub columns: usize,
    /// Rows.
    pub rows: usize,
}

impl SphereGrid {
    /// Distance between neighbouring centres.
    pub const SPACING: f64 = 2.4;
    /// Distance from the camera to the plane of the centres.
    pub const DISTANCE: f64 = 60.0;

    /// The grid of `count` spheres, `columns` per row (the last row may be short).
    pub fn new(count: usize, columns: usize) -> Result<Self> {
        if count == 0 || columns == 0 {
            return Err(RenderError::InvalidArgument(format!(
                "a grid of {count} spheres in {columns} columns"
            )));
        }
        let columns = columns.min(count);
        Ok(Self {
            columns,
            rows: count.div_ceil(columns),
        })
    }

    /// The middle of the grid (what the camera looks at).
    pub fn centre(&self) -> Vec3 {
        Vec3::new(
            (self.columns as f64 - 1.0) * Self::SPACING * 0.5,
            -(self.rows as f64 - 1.0) * Self::SPACING * 0.5,
            0.0,
        )
    }

    /// Centre of sphere `i` (row `i / columns` from the top, column `i % columns`).
    pub fn sphere(&self, i: usize) -> Vec3 {
        Vec3::new(
            (i % self.columns) as f64 * Self::SPACING,
            -((i / self.columns) as f64) * Self::SPACING,
            0.0,
        )
    }

    /// The camera: on +z, looking at [`Self::centre`], framing `sphere_pixels` per sphere.
    pub fn camera(&self, sphere_pixels: usize) -> Camera {
        let c = self.centre();
        Camera {
            position: c + Vec3::new(0.0, 0.0, Self::DISTANCE),
            look_at: c,
            up: Vec3::y(),
            fov_degrees: 2.0
                * (Self::SPACING * self.rows as f64 * 0.5 / Self::DISTANCE)
                    .atan()
                    .to_degrees(),
            width: sphere_pixels * self.columns,
            height: sphere_pixels * self.rows,
        }
    }

    /// The point light: far to the upper left, in front, with irradiance π at the centre.
    pub fn light(&self) -> PointLight {
        let c = self.centre();
        let position = c + Vec3::new(-400.0, 400.0, 600.0);
        PointLight {
            position,
            intensity: unit_intensity((position - c).norm()),
        }
    }
}

/// The spheres of `materials` in a [`SphereGrid`] of `columns` per row.
pub fn sphere_grid_scene(
    materials: Vec<SurfaceMaterial>,
    columns: usize,
    sphere_pixels: usize,
) -> Result<Scene> {
    let grid = SphereGrid::new(materials.len(), columns)?;
    let mut b = SceneBuilder::new(grid.camera(sphere_pixels));
    for (i, m) in materials.into_iter().enumerate() {
        let id = b.add_material(m);
        b.add_sphere(grid.sphere(i), 1.0, id)?;
    }
    b.add_point_light(grid.light())?;
    b.build()
}

/// A row of unit spheres, one per material (left to right), under a shared distant point
/// light; each sphere gets a `sphere_pixels` square of the image (a one-row
/// [`sphere_grid_scene`]).
pub fn strip_scene(materials: Vec<SurfaceMaterial>, sphere_pixels: usize) -> Result<Scene> {
    if materials.is_empty() {
        return Err(RenderError::InvalidArgument(
            "strip of zero materials".into(),
        ));
    }
    let n = materials.len();
    sphere_grid_scene(materials, n, sphere_pixels)
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

    #[test]
    fn each_grid_cell_sees_its_own_sphere() {
        let mats: Vec<SurfaceMaterial> = (0..7)
            .map(|_| {
                crate::material::Material::new(Arc::new(crate::Lambert { kd: [0.5; 3] })).into()
            })
            .collect();
        let px = 16;
        let scene = sphere_grid_scene(mats, 4, px).unwrap();
        let grid = SphereGrid::new(7, 4).unwrap();
        assert_eq!((grid.columns, grid.rows), (4, 2));
        assert_eq!((scene.camera.width, scene.camera.height), (64, 32));
        for i in 0..8 {
            let (cx, cy) = ((i % 4) * px + px / 2, (i / 4) * px + px / 2);
            let ray = scene.camera.ray(cx as f64 + 0.5, cy as f64 + 0.5);
            let hit = scene.intersect(&ray, f64::INFINITY);
            if i == 7 {
                assert!(hit.is_none(), "the eighth cell is empty");
                continue;
            }
            let hit = hit.expect("a sphere at the cell's centre");
            assert!((hit.point - grid.sphere(i)).norm() < 1.0 + 1e-9, "cell {i}");
            // the front of the sphere, facing the camera
            assert!(hit.point.z > 0.9, "cell {i}: {:?}", hit.point);
        }
        // one row is the strip
        let strip = SphereGrid::new(5, 9).unwrap();
        assert_eq!((strip.columns, strip.rows), (5, 1));
        assert!(SphereGrid::new(0, 3).is_err() && SphereGrid::new(3, 0).is_err());
    }

    #[test]
    fn the_shared_bunny_stands_where_the_teapot_stands() {
        let path = shared_bunny_path();
        let bunny = figure_bunny_mesh().unwrap_or_else(|e| {
            panic!(
                "shared bunny at {} ({e}); set BRDF_DATA_DIR",
                path.display()
            )
        });
        let (lo, hi) = bunny.bounds();
        assert!(
            lo.y.abs() < 1e-9 && (hi.y - BUNNY_HEIGHT).abs() < 1e-9,
            "{lo:?} {hi:?}"
        );
        assert!(((lo.x + hi.x) * 0.5).abs() < 1e-9 && ((lo.z + hi.z) * 0.5).abs() < 1e-9);
        assert_eq!(bunny.normals.len(), bunny.positions.len());
        assert_eq!(bunny.uvs.len(), bunny.positions.len());
        assert!(bunny.triangles.len() > 60_000);
        // the camera of the teapot figures sees it: the ray to the look-at point hits it
        let camera = teapot_camera(64, 48);
        let mut b = SceneBuilder::new(camera);
        let m = b.add_material(crate::material::Material::new(Arc::new(crate::Lambert {
            kd: [0.5; 3],
        })));
        b.add_mesh(&bunny, &Transform::default(), m).unwrap();
        b.add_point_light(teapot_point_light()).unwrap();
        let scene = b.build().unwrap();
        assert!(scene
            .intersect(&camera.ray(32.0, 24.0), f64::INFINITY)
            .is_some());
    }
}
