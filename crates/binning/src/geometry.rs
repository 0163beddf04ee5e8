//! Rig geometry as binning needs it, and the per-pixel geometry of the sample sphere.

use nalgebra::Vector3;

/// A world-space vector (metres).
pub type V3 = Vector3<f64>;

/// What binning needs to know about the rig's geometry (implemented by every holder of a
/// [`gantry_hal::RigGeometry`], such as the calibration file).
pub trait RigGeometry: Sync {
    /// Sensor size (columns, rows).
    fn sensor_size(&self) -> (usize, usize);
    /// World-space ray through pixel coordinates (`u`, `v`) (pixel centres are integers), with
    /// lens distortion removed: origin (the centre of projection) and unit direction.
    fn pixel_ray(&self, u: f64, v: f64) -> (V3, V3);
    /// Pixel coordinates of a world point, `None` behind the camera.
    fn project(&self, p: &V3) -> Option<[f64; 2]>;
    /// Lamp position at a turntable angle (degrees).
    fn lamp_position(&self, angle_deg: f64) -> V3;
    /// Sample sphere centre and radius.
    fn sphere(&self) -> (V3, f64);
}

/// Nearest intersection of a ray with a sphere (distance along the unit direction).
pub fn ray_sphere(origin: &V3, dir: &V3, centre: &V3, radius: f64) -> Option<f64> {
    let oc = origin - centre;
    let b = oc.dot(dir);
    let c = oc.norm_squared() - radius * radius;
    let disc = b * b - c;
    if disc < 0.0 {
        return None;
    }
    let s = disc.sqrt();
    let t = -b - s;
    if t > 0.0 {
        Some(t)
    } else {
        let t2 = -b + s;
        (t2 > 0.0).then_some(t2)
    }
}

/// One pixel that sees the sample sphere.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SpherePixel {
    /// Flat pixel index, `y · width + x`.
    pub index: u32,
    /// Bayer colour channel of the photosite (0 = R, 1 = G, 2 = B).
    pub channel: u8,
    /// Surface point hit by the pixel's ray.
    pub point: V3,
    /// Outward unit normal at the point.
    pub normal: V3,
    /// Unit direction from the point towards the camera.
    pub to_camera: V3,
}

/// The sphere pixels of the camera image.
///
/// Camera and sphere do not move during a capture, so the surface point, normal and view
/// direction of every sphere pixel are computed once ([`SphereView`]); only the lamp position
/// changes from one image to the next.
///
/// # Examples
///
/// ```
/// use binning::SphereView;
/// # use gantry_hal::{CameraIntrinsics, CameraPose, LampCircle, SphereGeometry};
/// # // a 128 × 128 camera 1 m from a 1-inch sphere; the lamp circle (0.5 m) starts beside it
/// # let rig = gantry_hal::RigGeometry {
/// #     camera: CameraIntrinsics::radial(128, 128, 2000.0, 2000.0, 64.0, 64.0, 0.0, 0.0),
/// #     pose: CameraPose::look_at([0.0, -1.0, 0.0], [0.0; 3], 0.0),
/// #     lamp: LampCircle { centre: [0.0; 3], normal: [0.0, 0.0, 1.0], radius: 0.5, reference: [0.0, -1.0, 0.0] },
/// #     sphere: SphereGeometry { centre: [0.0; 3], radius: 0.0254 },
/// # };
/// let view = SphereView::new(&rig, |x, y| gantry_hal::BayerPattern::Rggb.channel_at(x, y), 85.0);
/// // the sphere's image is a disc of about 2000 · 0.0254 = 51 pixels radius
/// let area = std::f64::consts::PI * 50.8f64.powi(2);
/// assert!((view.pixels.len() as f64 / area - 1.0).abs() < 0.05, "{}", view.pixels.len());
/// for p in &view.pixels {
///     assert!((p.normal.norm() - 1.0).abs() < 1e-9);
///     assert!(p.normal.dot(&p.to_camera) >= 85f64.to_radians().cos() - 1e-9);
/// }
/// ```
#[derive(Debug, Clone)]
pub struct SphereView {
    /// Sensor columns.
    pub width: usize,
    /// Sensor rows.
    pub height: usize,
    /// Pixels whose ray hits the sphere with a view angle below the limit, in row-major order.
    pub pixels: Vec<SpherePixel>,
}

impl SphereView {
    /// Traces every pixel centre. Pixels seeing the sphere at more than `max_view_deg` from the
    /// normal are left out (near the silhouette a pixel also sees the background).
    pub fn new(
        geom: &dyn RigGeometry,
        channel_at: impl Fn(usize, usize) -> usize + Sync,
        max_view_deg: f64,
    ) -> Self {
        use rayon::prelude::*;
        let (width, height) = geom.sensor_size();
        let (centre, radius) = geom.sphere();
        let cos_max = max_view_deg.to_radians().cos();
        // Only rows and columns inside the sphere's projected bounding box need tracing.
        let (x0, x1, y0, y1) = projected_box(geom, &centre, radius, width, height);
        let pixels: Vec<SpherePixel> = (y0..y1)
            .into_par_iter()
            .flat_map_iter(|y| {
                let channel_at = &channel_at;
                (x0..x1).filter_map(move |x| {
                    let (o, d) = geom.pixel_ray(x as f64, y as f64);
                    let t = ray_sphere(&o, &d, &centre, radius)?;
                    let p = o + d * t;
                    let n = (p - centre) / radius;
                    let to_cam = -d;
                    if n.dot(&to_cam) < cos_max {
                        return None;
                    }
                    Some(SpherePixel {
                        index: (y * width + x) as u32,
                        channel: channel_at(x, y) as u8,
                        point: p,
                        normal: n,
                        to_camera: to_cam,
                    })
                })
            })
            .collect();
        Self {
            width,
            height,
            pixels,
        }
    }
}

fn projected_box(
    geom: &dyn RigGeometry,
    centre: &V3,
    radius: f64,
    width: usize,
    height: usize,
) -> (usize, usize, usize, usize) {
    let mut lo = [f64::INFINITY; 2];
    let mut hi = [f64::NEG_INFINITY; 2];
    let mut any = false;
    // Points on the sphere's bounding cube cover its projection.
    for i in 0..27 {
        let d = V3::new(
            (i % 3) as f64 - 1.0,
            ((i / 3) % 3) as f64 - 1.0,
            (i / 9) as f64 - 1.0,
        );
        if let Some(p) = geom.project(&(centre + d * radius * 1.01)) {
            any = true;
            for k in 0..2 {
                lo[k] = lo[k].min(p[k]);
                hi[k] = hi[k].max(p[k]);
            }
        }
    }
    if !any {
        return (0, width, 0, height);
    }
    let clamp = |v: f64, n: usize| (v.max(0.0) as usize).min(n);
    (
        clamp(lo[0].floor() - 2.0, width),
        clamp(hi[0].ceil() + 3.0, width),
        clamp(lo[1].floor() - 2.0, height),
        clamp(hi[1].ceil() + 3.0, height),
    )
}

/// An orthonormal frame with `n` as its third axis.
pub fn frame_from_normal(n: &V3) -> (V3, V3) {
    let a = if n.x.abs() < 0.9 { V3::x() } else { V3::y() };
    let t = n.cross(&a).normalize();
    let b = n.cross(&t);
    (t, b)
}

/// `w` expressed in the local frame (t, b, n).
#[inline]
pub fn to_local(w: &V3, t: &V3, b: &V3, n: &V3) -> V3 {
    V3::new(w.dot(t), w.dot(b), w.dot(n))
}

/// Every holder of the rig's geometry (`gantry_hal::RigGeometry` itself, a
/// calibration file) is a [`RigGeometry`]: rays through the Brown–Conrady camera model.
impl<T: AsRef<gantry_hal::RigGeometry> + Sync> RigGeometry for T {
    fn sensor_size(&self) -> (usize, usize) {
        let c = &self.as_ref().camera;
        (c.width, c.height)
    }
    fn pixel_ray(&self, u: f64, v: f64) -> (V3, V3) {
        self.as_ref().pixel_ray_world(u, v)
    }
    fn project(&self, p: &V3) -> Option<[f64; 2]> {
        self.as_ref().project(p)
    }
    fn lamp_position(&self, angle_deg: f64) -> V3 {
        self.as_ref().lamp_position(angle_deg)
    }
    fn sphere(&self) -> (V3, f64) {
        let s = &self.as_ref().sphere;
        (V3::from(s.centre), s.radius)
    }
}
