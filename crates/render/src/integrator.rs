//! Integrators: direct illumination (thesis A.1) and Monte Carlo path tracing (A.2) with BRDF
//! importance sampling (A.2.4), light and environment sampling and multiple importance
//! sampling; tiles rendered in parallel with per-tile seeded random streams.

use crate::error::Result;
use crate::geometry::Ray;
use crate::image::Image;
use crate::importance::{BrdfImportance, PhiSampling};
use crate::material::{BasisBrdf, Material, SurfaceMaterial};
use crate::sampling::{
    cosine_hemisphere, cosine_hemisphere_pdf, power_heuristic, uniform, uniform_hemisphere,
    uniform_hemisphere_pdf, Frame, SampleRng,
};
use crate::scene::{Hit, Scene};
use brdf::{Brdf, Rgb, Vec3};
use rand::SeedableRng;
use rayon::prelude::*;
use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::Arc;

/// Which light transport estimate to compute.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Integrator {
    /// Direct illumination only (thesis A.1): light reflected once towards the camera.
    Direct,
    /// Monte Carlo path tracing (thesis A.2).
    #[default]
    PathTracing,
}

/// How reflected directions are chosen at surfaces.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum BsdfSampling {
    /// Uniform hemisphere (thesis A.2.3).
    Uniform,
    /// Cosine-weighted hemisphere.
    Cosine,
    /// BRDF importance sampling: the model's own sampler where it has one
    /// ([`brdf::Brdf::has_importance_sampler`]: Lambert, GGX by visible normals), else the
    /// tabulated importance tables (thesis A.2.4, with this φ method) where they exist, else
    /// the model's default sampler (cosine-weighted directions).
    Importance(PhiSampling),
}

impl Default for BsdfSampling {
    fn default() -> Self {
        BsdfSampling::Importance(PhiSampling::Inversion)
    }
}

/// Pixel index, mean and variance of the mean.
type PixelResult = (usize, [f64; 3], [f64; 3]);

/// Progress callback: `(tiles done, tiles total)`.
pub type ProgressFn = Arc<dyn Fn(usize, usize) + Send + Sync>;

/// Rendering parameters.
#[derive(Clone)]
pub struct RenderOptions {
    /// Samples per pixel.
    pub spp: u32,
    /// Seed of all random streams (output is identical for equal seeds).
    pub seed: u64,
    /// Integrator.
    pub integrator: Integrator,
    /// Maximum number of bounces for path tracing (1 = direct lighting only).
    pub max_depth: u32,
    /// Direction sampling at surfaces.
    pub bsdf_sampling: BsdfSampling,
    /// Sample lights explicitly (next-event estimation). Without it, only BRDF-sampled rays
    /// that hit emitters or the environment carry light (point lights then contribute nothing).
    pub next_event: bool,
    /// Combine light and BRDF sampling with the power heuristic. Without it (and with
    /// `next_event`), emitters are reached only by light sampling.
    pub mis: bool,
    /// Light (and, with MIS, BRDF) samples per pixel sample for the direct integrator.
    pub light_samples: u32,
    /// Tile side in pixels.
    pub tile_size: usize,
    /// Depth from which Russian roulette may end paths.
    pub russian_roulette_depth: u32,
    /// Called after each finished tile.
    pub progress: Option<ProgressFn>,
}

impl std::fmt::Debug for RenderOptions {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("RenderOptions")
            .field("spp", &self.spp)
            .field("seed", &self.seed)
            .field("integrator", &self.integrator)
            .field("max_depth", &self.max_depth)
            .field("bsdf_sampling", &self.bsdf_sampling)
            .field("next_event", &self.next_event)
            .field("mis", &self.mis)
            .field("light_samples", &self.light_samples)
            .finish()
    }
}

impl Default for RenderOptions {
    fn default() -> Self {
        Self {
            spp: 64,
            seed: 0,
            integrator: Integrator::PathTracing,
            max_depth: 8,
            bsdf_sampling: BsdfSampling::default(),
            next_event: true,
            mis: true,
            light_samples: 1,
            tile_size: 16,
            russian_roulette_depth: 5,
            progress: None,
        }
    }
}

/// A rendered image with the per-pixel variance of its mean (for confidence intervals).
#[derive(Debug, Clone)]
pub struct RenderOutput {
    /// Mean radiance per pixel.
    pub image: Image,
    /// Variance of each pixel's mean, per channel.
    pub variance: Image,
    /// Total number of camera samples taken.
    pub samples: u64,
    /// Samples whose value was not finite and were dropped.
    pub dropped: u64,
}

/// Renders `scene`; the mean image only.
pub fn render_scene(scene: &Scene, options: &RenderOptions) -> Result<Image> {
    Ok(render_with_variance(scene, options)?.image)
}

/// Renders `scene` and also returns per-pixel variances.
pub fn render_with_variance(scene: &Scene, options: &RenderOptions) -> Result<RenderOutput> {
    let cam = &scene.camera;
    let (w, h) = (cam.width, cam.height);
    let ts = options.tile_size.max(1);
    let tiles_x = w.div_ceil(ts);
    let tiles_y = h.div_ceil(ts);
    let total = tiles_x * tiles_y;
    let spp = options.spp.max(1);
    let done = AtomicUsize::new(0);
    let tiles: Vec<(Vec<PixelResult>, u64)> = (0..total)
        .into_par_iter()
        .map(|tile| {
            let mut rng = SampleRng::seed_from_u64(options.seed);
            rng.set_stream(tile as u64 + 1);
            let (tx, ty) = (tile % tiles_x, tile / tiles_x);
            let mut out = Vec::with_capacity(ts * ts);
            let mut dropped = 0u64;
            for y in ty * ts..((ty + 1) * ts).min(h) {
                for x in tx * ts..((tx + 1) * ts).min(w) {
                    let mut s = [0.0; 3];
                    let mut s2 = [0.0; 3];
                    for _ in 0..spp {
                        let ray =
                            cam.ray(x as f64 + uniform(&mut rng), y as f64 + uniform(&mut rng));
                        let l = radiance(scene, &ray, options, &mut rng);
                        if l.iter().all(|v| v.is_finite()) {
                            for c in 0..3 {
                                s[c] += l[c];
                                s2[c] += l[c] * l[c];
                            }
                        } else {
                            dropped += 1;
                        }
                    }
                    let n = spp as f64;
                    let mean = s.map(|v| v / n);
                    let mut var = [0.0; 3];
                    if spp > 1 {
                        for c in 0..3 {
                            var[c] = ((s2[c] - n * mean[c] * mean[c]) / (n - 1.0)).max(0.0) / n;
                        }
                    }
                    out.push((y * w + x, mean, var));
                }
            }
            let d = done.fetch_add(1, Ordering::Relaxed) + 1;
            if let Some(p) = &options.progress {
                p(d, total);
            }
            (out, dropped)
        })
        .collect();
    let mut image = Image::new(w, h)?;
    let mut variance = Image::new(w, h)?;
    let mut dropped = 0;
    for (tile, d) in tiles {
        dropped += d;
        for (i, m, v) in tile {
            image.pixels_mut()[i] = m.map(|x| x as f32);
            variance.pixels_mut()[i] = v.map(|x| x as f32);
        }
    }
    if dropped > 0 {
        tracing::warn!(dropped, "non-finite radiance samples dropped");
    }
    Ok(RenderOutput {
        image,
        variance,
        samples: (w * h) as u64 * spp as u64,
        dropped,
    })
}

/// Radiance arriving at the camera along `ray` (one sample).
pub fn radiance(scene: &Scene, ray: &Ray, options: &RenderOptions, rng: &mut SampleRng) -> Rgb {
    match options.integrator {
        Integrator::Direct => direct_radiance(scene, ray, options, rng),
        Integrator::PathTracing => path_radiance(scene, ray, options, rng),
    }
}

/// One BRDF of a shading point: a scene material, or the point's own BRDF of a spatially
/// varying material (its coefficients sampled from the texture at the hit).
enum Lobe<'a> {
    Shared(&'a Material),
    Texel(BasisBrdf),
}

impl Lobe<'_> {
    fn brdf(&self) -> &dyn Brdf {
        match self {
            Lobe::Shared(m) => m.brdf.as_ref(),
            Lobe::Texel(b) => b,
        }
    }

    /// Where the lobe's importance sampling comes from: the per-point BRDF has no tables, so it
    /// is sampled like a [`Material::new`] material (the model's default sampler).
    fn source(&self) -> ImportanceSource<'_> {
        match self {
            Lobe::Shared(m) => importance_source(m),
            Lobe::Texel(_) => ImportanceSource::Model,
        }
    }
}

/// Local shading state at a hit: frame, outgoing direction, one or two weighted BRDFs.
struct Shading<'a> {
    frame: Frame,
    wo: Vec3,
    first: (f64, Lobe<'a>),
    second: Option<(f64, Lobe<'a>)>,
}

impl<'a> Shading<'a> {
    fn new(scene: &'a Scene, hit: &Hit, to_viewer: &Vec3) -> Option<Self> {
        let material = &scene.materials[hit.material?];
        let mut frame = Frame::from_normal(&hit.shading_normal);
        let mut wo = frame.to_local(to_viewer);
        if wo.z <= 1e-9 {
            frame = Frame::from_normal(&hit.geometric_normal);
            wo = frame.to_local(to_viewer);
            if wo.z <= 1e-9 {
                return None;
            }
        }
        let (first, second) = match material {
            SurfaceMaterial::Single(m) => ((1.0, Lobe::Shared(m)), None),
            SurfaceMaterial::Blend { a, b, mask } => {
                let t = mask.weight(&hit.point, hit.uv);
                if t <= 0.0 {
                    ((1.0, Lobe::Shared(a)), None)
                } else if t >= 1.0 {
                    ((1.0, Lobe::Shared(b)), None)
                } else {
                    ((1.0 - t, Lobe::Shared(a)), Some((t, Lobe::Shared(b))))
                }
            }
            SurfaceMaterial::Varying { basis, texture } => {
                let c = texture.sample(hit.uv).into_boxed_slice();
                let brdf = BasisBrdf::from_f32(basis.clone(), c);
                ((1.0, Lobe::Texel(brdf)), None)
            }
        };
        Some(Self {
            frame,
            wo,
            first,
            second,
        })
    }

    fn lobes(&self) -> impl Iterator<Item = &(f64, Lobe<'a>)> {
        std::iter::once(&self.first).chain(self.second.as_ref())
    }

    fn eval(&self, wi: &Vec3) -> Rgb {
        let mut f = [0.0; 3];
        if wi.z <= 0.0 {
            return f;
        }
        for (w, m) in self.lobes() {
            let v = m.brdf().eval(wi, &self.wo);
            for c in 0..3 {
                let x = v[c];
                if x.is_finite() && x > 0.0 {
                    f[c] += w * x;
                }
            }
        }
        f
    }

    fn pdf(&self, wi: &Vec3, strategy: BsdfSampling) -> f64 {
        self.lobes()
            .map(|(w, m)| w * component_pdf(m, &self.wo, wi, strategy))
            .sum()
    }

    fn sample(&self, strategy: BsdfSampling, rng: &mut SampleRng) -> Option<(Vec3, f64)> {
        let m = match &self.second {
            Some((_, b)) if uniform(rng) >= self.first.0 => b,
            _ => &self.first.1,
        };
        let (wi, sampled_pdf) = match strategy {
            BsdfSampling::Uniform => (uniform_hemisphere(uniform(rng), uniform(rng)), None),
            BsdfSampling::Cosine => (cosine_hemisphere(uniform(rng), uniform(rng)), None),
            BsdfSampling::Importance(v) => match m.source() {
                ImportanceSource::Model => {
                    let s = m
                        .brdf()
                        .sample(&self.wo, [uniform(rng), uniform(rng), uniform(rng)])?;
                    (s.wi, Some(s.pdf))
                }
                ImportanceSource::Tables(t) => {
                    let (wi, p) = t.sample(&self.wo, v, rng)?;
                    (wi, Some(p))
                }
            },
        };
        // The model's or the table's sampler returns its own density (the same `pdf` call): with
        // one material it is the mixture's density, so it is not evaluated a second time.
        let p = match sampled_pdf {
            Some(p) if self.second.is_none() => p,
            _ => self.pdf(&wi, strategy),
        };
        (p > 0.0 && wi.z > 0.0).then_some((wi, p))
    }
}

/// Where a material's importance sampling comes from: the model's own sampler
/// ([`brdf::Brdf::sample`]: exact for the analytic models that have one, cosine-weighted for the
/// others), unless the model has none of its own and importance tables (thesis A.2.4) were built.
enum ImportanceSource<'a> {
    Model,
    Tables(&'a BrdfImportance),
}

fn importance_source(m: &Material) -> ImportanceSource<'_> {
    match &m.importance {
        Some(t) if !m.brdf.has_importance_sampler() => ImportanceSource::Tables(t),
        _ => ImportanceSource::Model,
    }
}

fn component_pdf(m: &Lobe, wo: &Vec3, wi: &Vec3, strategy: BsdfSampling) -> f64 {
    match strategy {
        BsdfSampling::Uniform => uniform_hemisphere_pdf(wi),
        BsdfSampling::Cosine => cosine_hemisphere_pdf(wi),
        BsdfSampling::Importance(_) => match m.source() {
            ImportanceSource::Model => m.brdf().pdf(wi, wo),
            ImportanceSource::Tables(t) => t.pdf(wo, wi),
        },
    }
}

fn spawn_origin(scene: &Scene, hit: &Hit, dir: &Vec3) -> Vec3 {
    let scale = 1e-6 * (1.0 + hit.point.amax()) + scene.ray_epsilon();
    let side = if dir.dot(&hit.geometric_normal) >= 0.0 {
        1.0
    } else {
        -1.0
    };
    hit.point + hit.geometric_normal * (side * scale)
}

/// Whether `target` is visible from the hit point. The shadow ray starts at the offset origin
/// and is aimed at `target` from there (aiming it along `dir`, computed from the un-offset hit
/// point, would make it cross the target's own surface early and report the light occluded).
fn visible(scene: &Scene, hit: &Hit, dir: &Vec3, target: &Vec3) -> bool {
    let origin = spawn_origin(scene, hit, dir);
    let to = target - origin;
    let dist = to.norm();
    if dist <= 0.0 || !dist.is_finite() {
        return false;
    }
    !scene.occluded(&origin, &(to / dist), dist)
}

fn add_scaled(acc: &mut Rgb, a: &Rgb, b: &Rgb, s: f64) {
    for c in 0..3 {
        acc[c] += a[c] * b[c] * s;
    }
}

/// Solid-angle density of sampling area light `j` uniformly by area, seen from `origin`
/// towards `point`.
fn area_light_pdf(scene: &Scene, j: usize, origin: &Vec3, point: &Vec3) -> f64 {
    let l = &scene.area_lights[j];
    let d = point - origin;
    let dist2 = d.norm_squared();
    let cos_l = l.normal().dot(&(-d / dist2.sqrt())).abs();
    if cos_l <= 0.0 {
        return 0.0;
    }
    dist2 / (cos_l * l.area())
}

/// Next-event estimation at a surface: every point light, one sample per area light and one
/// environment sample, each MIS-weighted against BRDF sampling when `mis` is on.
fn sample_lights(
    scene: &Scene,
    hit: &Hit,
    sh: &Shading,
    options: &RenderOptions,
    rng: &mut SampleRng,
) -> Rgb {
    let mut l = [0.0; 3];
    // The light sample's multiple-importance weight against BSDF sampling.
    let mis_weight = |wi: &Vec3, pdf_light: f64| {
        if options.mis {
            power_heuristic(pdf_light, sh.pdf(wi, options.bsdf_sampling))
        } else {
            1.0
        }
    };
    for pl in &scene.point_lights {
        let d = pl.position - hit.point;
        let dist = d.norm();
        if dist <= 0.0 {
            continue;
        }
        let wi_w = d / dist;
        let wi = sh.frame.to_local(&wi_w);
        if wi.z <= 0.0 {
            continue;
        }
        if !visible(scene, hit, &wi_w, &pl.position) {
            continue;
        }
        let f = sh.eval(&wi);
        add_scaled(&mut l, &f, &pl.intensity, wi.z / (dist * dist));
    }
    for (j, al) in scene.area_lights.iter().enumerate() {
        let x = al.point(uniform(rng), uniform(rng));
        let d = x - hit.point;
        let dist = d.norm();
        if dist <= 0.0 {
            continue;
        }
        let wi_w = d / dist;
        let le = al.emitted(&-wi_w);
        if le.iter().all(|&v| v == 0.0) {
            continue;
        }
        let wi = sh.frame.to_local(&wi_w);
        if wi.z <= 0.0 {
            continue;
        }
        let pdf_light = area_light_pdf(scene, j, &hit.point, &x);
        if !(pdf_light > 0.0 && pdf_light.is_finite()) {
            continue;
        }
        if !visible(scene, hit, &wi_w, &x) {
            continue;
        }
        let f = sh.eval(&wi);
        add_scaled(
            &mut l,
            &f,
            &le,
            wi.z * mis_weight(&wi, pdf_light) / pdf_light,
        );
    }
    if let Some(env) = &scene.environment {
        if let Some((wi_w, le, pdf_light)) = env.sample(rng) {
            let wi = sh.frame.to_local(&wi_w);
            if wi.z > 0.0 && pdf_light > 0.0 {
                let origin = spawn_origin(scene, hit, &wi_w);
                if !scene.occluded(&origin, &wi_w, f64::INFINITY) {
                    let f = sh.eval(&wi);
                    let w = mis_weight(&wi, pdf_light);
                    add_scaled(&mut l, &f, &le, wi.z * w / pdf_light);
                }
            }
        }
    }
    l
}

/// Weight of emission reached by a BRDF-sampled ray with density `bsdf_pdf`.
fn emission_weight(
    options: &RenderOptions,
    bsdf_pdf: Option<f64>,
    light_pdf: impl Fn() -> f64,
) -> f64 {
    match bsdf_pdf {
        None => 1.0,
        Some(p) => {
            if !options.next_event {
                1.0
            } else if !options.mis {
                0.0
            } else {
                power_heuristic(p, light_pdf())
            }
        }
    }
}

fn path_radiance(
    scene: &Scene,
    camera_ray: &Ray,
    options: &RenderOptions,
    rng: &mut SampleRng,
) -> Rgb {
    let mut l = [0.0; 3];
    let mut beta = [1.0; 3];
    let mut ray = *camera_ray;
    let mut prev_pdf: Option<f64> = None;
    let mut depth = 0u32;
    loop {
        let Some(hit) = scene.intersect(&ray, f64::INFINITY) else {
            if let Some(env) = &scene.environment {
                let le = env.radiance(&ray.direction);
                let w = emission_weight(options, prev_pdf, || env.pdf(&ray.direction));
                add_scaled(&mut l, &beta, &le, w);
            }
            break;
        };
        if let Some(j) = hit.light {
            let le = scene.area_lights[j].emitted(&-ray.direction);
            let w = emission_weight(options, prev_pdf, || {
                area_light_pdf(scene, j, &ray.origin, &hit.point)
            });
            add_scaled(&mut l, &beta, &le, w);
            break;
        }
        if depth >= options.max_depth {
            break;
        }
        let Some(sh) = Shading::new(scene, &hit, &-ray.direction) else {
            break;
        };
        if options.next_event {
            let d = sample_lights(scene, &hit, &sh, options, rng);
            add_scaled(&mut l, &beta, &d, 1.0);
        }
        let Some((wi, pdf)) = sh.sample(options.bsdf_sampling, rng) else {
            break;
        };
        let f = sh.eval(&wi);
        for c in 0..3 {
            beta[c] *= f[c] * wi.z / pdf;
        }
        if beta.iter().all(|&b| b <= 0.0) || beta.iter().any(|b| !b.is_finite()) {
            break;
        }
        depth += 1;
        if depth >= options.russian_roulette_depth {
            let q = beta.iter().cloned().fold(0.0, f64::max).min(0.95);
            if uniform(rng) >= q {
                break;
            }
            beta = beta.map(|b| b / q);
        }
        let wi_w = sh.frame.to_world(&wi);
        ray = Ray::new(spawn_origin(scene, &hit, &wi_w), wi_w);
        prev_pdf = Some(pdf);
    }
    l
}

fn direct_radiance(scene: &Scene, ray: &Ray, options: &RenderOptions, rng: &mut SampleRng) -> Rgb {
    let Some(hit) = scene.intersect(ray, f64::INFINITY) else {
        return scene
            .environment
            .as_ref()
            .map_or([0.0; 3], |e| e.radiance(&ray.direction));
    };
    if let Some(j) = hit.light {
        return scene.area_lights[j].emitted(&-ray.direction);
    }
    let Some(sh) = Shading::new(scene, &hit, &-ray.direction) else {
        return [0.0; 3];
    };
    let n = options.light_samples.max(1);
    let mut l = [0.0; 3];
    // light sampling (A.1 sums over the lights; area lights and the environment are sampled)
    let light_opts = RenderOptions {
        mis: options.mis,
        ..options.clone()
    };
    for _ in 0..n {
        let d = sample_lights(scene, &hit, &sh, &light_opts, rng);
        add_scaled(&mut l, &d, &[1.0; 3], 1.0 / n as f64);
    }
    if options.mis {
        // the BRDF-sampling half of MIS, for area lights and the environment
        for _ in 0..n {
            let Some((wi, pdf)) = sh.sample(options.bsdf_sampling, rng) else {
                continue;
            };
            let wi_w = sh.frame.to_world(&wi);
            let r = Ray::new(spawn_origin(scene, &hit, &wi_w), wi_w);
            let (le, light_pdf) = match scene.intersect(&r, f64::INFINITY) {
                None => match &scene.environment {
                    Some(env) => (env.radiance(&wi_w), env.pdf(&wi_w)),
                    None => continue,
                },
                Some(h2) => match h2.light {
                    Some(j) => (
                        scene.area_lights[j].emitted(&-wi_w),
                        area_light_pdf(scene, j, &r.origin, &h2.point),
                    ),
                    None => continue,
                },
            };
            let f = sh.eval(&wi);
            let w = power_heuristic(pdf, light_pdf);
            add_scaled(&mut l, &f, &le, wi.z * w / (pdf * n as f64));
        }
    }
    l
}
