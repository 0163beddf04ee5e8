//! Scenes: camera, shapes with materials, point and area lights, environment, BVH.

use crate::envmap::EnvironmentMap;
use crate::error::{RenderError, Result};
use crate::geometry::{Bvh, Ray, Shape};
use crate::material::SurfaceMaterial;
use crate::mesh::{Mesh, Transform};
use brdf::{Rgb, Vec3};

/// Index of a material in a scene.
pub type MaterialId = usize;

/// A pinhole camera.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Camera {
    /// Eye position.
    pub position: Vec3,
    /// Point looked at.
    pub look_at: Vec3,
    /// Approximate up direction.
    pub up: Vec3,
    /// Vertical field of view, degrees.
    pub fov_degrees: f64,
    /// Image width in pixels.
    pub width: usize,
    /// Image height in pixels.
    pub height: usize,
}

impl Camera {
    /// Checks sizes and directions.
    pub fn validate(&self) -> Result<()> {
        let fin = |v: &Vec3| v.iter().all(|x| x.is_finite());
        if self.width == 0 || self.height == 0 || self.width * self.height > 1 << 26 {
            return Err(RenderError::InvalidArgument(format!(
                "camera resolution {}×{}",
                self.width, self.height
            )));
        }
        if !(self.fov_degrees > 0.0 && self.fov_degrees < 179.0) {
            return Err(RenderError::InvalidArgument(format!(
                "camera field of view {}",
                self.fov_degrees
            )));
        }
        let fwd = self.look_at - self.position;
        if !fin(&self.position) || !fin(&self.look_at) || !fin(&self.up) || fwd.norm() == 0.0 {
            return Err(RenderError::InvalidArgument(
                "camera position/look_at".into(),
            ));
        }
        if fwd.cross(&self.up).norm() < 1e-12 {
            return Err(RenderError::InvalidArgument(
                "camera up is parallel to the view direction".into(),
            ));
        }
        Ok(())
    }

    /// Primary ray through image position `(x, y)` in pixels (y down, continuous).
    pub fn ray(&self, x: f64, y: f64) -> Ray {
        let fwd = (self.look_at - self.position).normalize();
        let right = fwd.cross(&self.up).normalize();
        let up = right.cross(&fwd);
        let h = (self.fov_degrees.to_radians() * 0.5).tan();
        let aspect = self.width as f64 / self.height as f64;
        let sx = (2.0 * x / self.width as f64 - 1.0) * h * aspect;
        let sy = (1.0 - 2.0 * y / self.height as f64) * h;
        Ray::new(self.position, (fwd + right * sx + up * sy).normalize())
    }
}

/// An isotropic point light.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PointLight {
    /// Position.
    pub position: Vec3,
    /// Radiant intensity, W/sr per channel.
    pub intensity: Rgb,
}

/// A one-sided emitting parallelogram `corner + s·edge_u + t·edge_v`, emitting towards
/// `edge_u × edge_v`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct AreaLight {
    /// One corner.
    pub corner: Vec3,
    /// First edge.
    pub edge_u: Vec3,
    /// Second edge.
    pub edge_v: Vec3,
    /// Emitted radiance per channel.
    pub radiance: Rgb,
}

impl AreaLight {
    /// Unit normal (emitting side).
    pub fn normal(&self) -> Vec3 {
        self.edge_u.cross(&self.edge_v).normalize()
    }

    /// Area.
    pub fn area(&self) -> f64 {
        self.edge_u.cross(&self.edge_v).norm()
    }

    /// Uniform point on the light.
    pub fn point(&self, s: f64, t: f64) -> Vec3 {
        self.corner + self.edge_u * s + self.edge_v * t
    }

    /// Radiance leaving towards direction `to_viewer` (zero from the back).
    pub fn emitted(&self, to_viewer: &Vec3) -> Rgb {
        if self.normal().dot(to_viewer) > 0.0 {
            self.radiance
        } else {
            [0.0; 3]
        }
    }
}

/// One renderable primitive.
#[derive(Debug, Clone, Copy)]
pub(crate) struct PrimitiveInfo {
    pub material: Option<MaterialId>,
    pub light: Option<usize>,
}

/// A surface hit.
#[derive(Debug, Clone, Copy)]
pub struct Hit {
    /// Ray parameter.
    pub t: f64,
    /// Hit point.
    pub point: Vec3,
    /// Geometric normal, flipped to face the incoming ray.
    pub geometric_normal: Vec3,
    /// Shading normal, on the same side as the geometric normal.
    pub shading_normal: Vec3,
    /// Texture coordinates.
    pub uv: [f64; 2],
    /// Material of the surface, `None` for lights.
    pub material: Option<MaterialId>,
    /// Area light index when the surface is an emitter.
    pub light: Option<usize>,
}

/// A renderable scene (built by [`SceneBuilder`]).
#[derive(Debug, Clone)]
pub struct Scene {
    /// The camera.
    pub camera: Camera,
    pub(crate) shapes: Vec<Shape>,
    pub(crate) info: Vec<PrimitiveInfo>,
    pub(crate) bvh: Bvh,
    /// Materials by id.
    pub materials: Vec<SurfaceMaterial>,
    /// Point lights.
    pub point_lights: Vec<PointLight>,
    /// Area lights.
    pub area_lights: Vec<AreaLight>,
    /// Environment map (radiance for rays that leave the scene).
    pub environment: Option<EnvironmentMap>,
    /// Scale of the scene (bounding-box diagonal), for ray epsilons.
    pub(crate) extent: f64,
}

impl Scene {
    /// Nearest surface hit in `(ε, t_max)`.
    pub fn intersect(&self, ray: &Ray, t_max: f64) -> Option<Hit> {
        let eps = self.ray_epsilon();
        let (idx, t, bary) = self.bvh.intersect(&self.shapes, ray, eps, t_max)?;
        let point = ray.at(t);
        let (mut ng, mut ns, uv) = self.shapes[idx].surface(&point, bary);
        if ng.dot(&ray.direction) > 0.0 {
            ng = -ng;
            ns = -ns;
        }
        let info = self.info[idx];
        Some(Hit {
            t,
            point,
            geometric_normal: ng,
            shading_normal: ns,
            uv,
            material: info.material,
            light: info.light,
        })
    }

    /// Whether the segment from `origin` along `direction` is blocked before `distance`.
    pub fn occluded(&self, origin: &Vec3, direction: &Vec3, distance: f64) -> bool {
        let eps = self.ray_epsilon();
        let ray = Ray::new(*origin, *direction);
        self.bvh
            .occluded(&self.shapes, &ray, eps, distance * (1.0 - 1e-6) - eps)
    }

    pub(crate) fn ray_epsilon(&self) -> f64 {
        1e-7 * self.extent.max(1.0)
    }

    /// Number of primitives.
    pub fn primitive_count(&self) -> usize {
        self.shapes.len()
    }
}

/// Incremental construction of a [`Scene`].
#[derive(Debug, Clone)]
pub struct SceneBuilder {
    camera: Camera,
    shapes: Vec<Shape>,
    info: Vec<PrimitiveInfo>,
    materials: Vec<SurfaceMaterial>,
    point_lights: Vec<PointLight>,
    area_lights: Vec<AreaLight>,
    environment: Option<EnvironmentMap>,
}

impl SceneBuilder {
    /// Starts a scene seen through `camera`.
    pub fn new(camera: Camera) -> Self {
        Self {
            camera,
            shapes: Vec::new(),
            info: Vec::new(),
            materials: Vec::new(),
            point_lights: Vec::new(),
            area_lights: Vec::new(),
            environment: None,
        }
    }

    /// Registers a material and returns its id.
    pub fn add_material(&mut self, m: impl Into<SurfaceMaterial>) -> MaterialId {
        self.materials.push(m.into());
        self.materials.len() - 1
    }

    fn check_material(&self, id: MaterialId) -> Result<()> {
        if id >= self.materials.len() {
            return Err(RenderError::InvalidArgument(format!(
                "unknown material id {id}"
            )));
        }
        Ok(())
    }

    /// Adds a sphere.
    pub fn add_sphere(&mut self, center: Vec3, radius: f64, material: MaterialId) -> Result<()> {
        self.check_material(material)?;
        if !(radius > 0.0 && radius.is_finite() && center.iter().all(|x| x.is_finite())) {
            return Err(RenderError::InvalidArgument(format!(
                "sphere at {center:?} radius {radius}"
            )));
        }
        self.shapes.push(Shape::Sphere { center, radius });
        self.info.push(PrimitiveInfo {
            material: Some(material),
            light: None,
        });
        Ok(())
    }

    /// Adds a triangle mesh under a transform.
    pub fn add_mesh(
        &mut self,
        mesh: &Mesh,
        transform: &Transform,
        material: MaterialId,
    ) -> Result<()> {
        self.check_material(material)?;
        mesh.validate()?;
        let m = mesh.transformed(transform);
        let has_n = !m.normals.is_empty();
        let has_uv = !m.uvs.is_empty();
        for t in &m.triangles {
            let p = t.map(|i| m.positions[i as usize]);
            if (p[1] - p[0]).cross(&(p[2] - p[0])).norm() <= 0.0 {
                continue;
            }
            let n = has_n.then(|| t.map(|i| m.normals[i as usize]));
            let uv = if has_uv {
                t.map(|i| m.uvs[i as usize])
            } else {
                [[0.0; 2]; 3]
            };
            self.shapes.push(Shape::Triangle { p, n, uv });
            self.info.push(PrimitiveInfo {
                material: Some(material),
                light: None,
            });
        }
        Ok(())
    }

    /// Adds a square ground plane of side `size` at height `y`, centred below `center`.
    pub fn add_ground(
        &mut self,
        y: f64,
        size: f64,
        center: [f64; 2],
        material: MaterialId,
    ) -> Result<()> {
        if !(size > 0.0 && size.is_finite() && y.is_finite()) {
            return Err(RenderError::InvalidArgument(format!("ground size {size}")));
        }
        let h = size * 0.5;
        let (cx, cz) = (center[0], center[1]);
        let mesh = Mesh {
            positions: vec![
                Vec3::new(cx - h, y, cz - h),
                Vec3::new(cx - h, y, cz + h),
                Vec3::new(cx + h, y, cz + h),
                Vec3::new(cx + h, y, cz - h),
            ],
            normals: vec![],
            uvs: vec![[0.0, 0.0], [0.0, 1.0], [1.0, 1.0], [1.0, 0.0]],
            triangles: vec![[0, 1, 2], [0, 2, 3]],
        };
        self.add_mesh(&mesh, &Transform::default(), material)
    }

    /// Adds a point light.
    pub fn add_point_light(&mut self, light: PointLight) -> Result<()> {
        if !light.position.iter().all(|x| x.is_finite())
            || light.intensity.iter().any(|x| !x.is_finite() || *x < 0.0)
        {
            return Err(RenderError::InvalidArgument(format!(
                "point light {light:?}"
            )));
        }
        self.point_lights.push(light);
        Ok(())
    }

    /// Adds a parallelogram area light (visible to camera rays, one-sided).
    pub fn add_area_light(&mut self, light: AreaLight) -> Result<()> {
        if !(light.area() > 0.0 && light.area().is_finite())
            || light.radiance.iter().any(|x| !x.is_finite() || *x < 0.0)
        {
            return Err(RenderError::InvalidArgument(format!(
                "area light {light:?}"
            )));
        }
        let id = self.area_lights.len();
        self.area_lights.push(light);
        let c = light.corner;
        let (u, v) = (light.edge_u, light.edge_v);
        for p in [[c, c + u, c + u + v], [c, c + u + v, c + v]] {
            self.shapes.push(Shape::Triangle {
                p,
                n: None,
                uv: [[0.0; 2]; 3],
            });
            self.info.push(PrimitiveInfo {
                material: None,
                light: Some(id),
            });
        }
        Ok(())
    }

    /// Sets the environment map.
    pub fn set_environment(&mut self, env: EnvironmentMap) {
        self.environment = Some(env);
    }

    /// Replaces the camera.
    pub fn set_camera(&mut self, camera: Camera) {
        self.camera = camera;
    }

    /// Builds the BVH and returns the scene.
    pub fn build(self) -> Result<Scene> {
        self.camera.validate()?;
        let bvh = Bvh::build(&self.shapes);
        let mut lo = self.camera.position;
        let mut hi = self.camera.position;
        for s in &self.shapes {
            let b = s.bounds();
            lo = lo.inf(&b.min);
            hi = hi.sup(&b.max);
        }
        let extent = (hi - lo).norm();
        Ok(Scene {
            camera: self.camera,
            shapes: self.shapes,
            info: self.info,
            bvh,
            materials: self.materials,
            point_lights: self.point_lights,
            area_lights: self.area_lights,
            environment: self.environment,
            extent,
        })
    }
}
