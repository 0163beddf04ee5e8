//! Environment lighting: latitude-longitude light probes with importance sampling.

use crate::distribution::Distribution2D;
use crate::error::{RenderError, Result};
use crate::image::Image;
use crate::sampling::{uniform, SampleRng};
use brdf::{Rgb, Vec3};
use rand::{Rng, SeedableRng};
use std::f64::consts::{PI, TAU};
use std::path::Path;

/// A lat-long environment map with its sampling distribution.
///
/// Mapping (world y up): a direction d has polar angle θ = acos(d.y) from +y and azimuth
/// φ = atan2(d.x, −d.z) ∈ [0, 2π); pixel column u = φ / 2π, row v = θ / π (top row = zenith).
/// Lookups are nearest-pixel, so the sampling density (pixel luminance × sin θ, piecewise
/// constant over pixels) is exact for the radiance function actually used.
#[derive(Debug, Clone)]
///
/// # Examples
///
/// ```
/// use brdf::Vec3;
/// use rand::SeedableRng;
/// use render::{EnvironmentMap, SampleRng};
/// use std::f64::consts::PI;
///
/// // A uniform sky: the same radiance from every direction, ∫ L dω = 4π L.
/// let sky = EnvironmentMap::constant([1.0, 0.5, 0.25]).unwrap();
/// assert_eq!(sky.radiance(&Vec3::new(0.3, -0.8, 0.1)), [1.0, 0.5, 0.25]);
/// let total = sky.integral();
/// assert!((total[0] - 4.0 * PI).abs() < 1e-6 && (total[2] - PI).abs() < 1e-6);
/// let brighter = EnvironmentMap::constant([1.0; 3]).unwrap().with_scale(2.0);
/// assert!((brighter.integral()[1] - 8.0 * PI).abs() < 1e-6);
///
/// // A procedural probe: samples follow luminance, and their density is the one pdf() reports.
/// let probe = EnvironmentMap::procedural_probe(64, 32, 7).unwrap();
/// let mut rng = SampleRng::seed_from_u64(5);
/// for _ in 0..100 {
///     let (d, radiance, pdf) = probe.sample(&mut rng).unwrap();
///     assert!((d.norm() - 1.0).abs() < 1e-9 && pdf > 0.0);
///     assert!((pdf - probe.pdf(&d)).abs() <= 1e-9 * pdf);
///     assert_eq!(radiance, probe.radiance(&d));
/// }
/// ```
pub struct EnvironmentMap {
    image: Image,
    scale: f64,
    rotation: f64,
    distribution: Option<Distribution2D>,
    /// The radiance of a map whose pixels are all equal (a constant environment): then
    /// lookups need no direction-to-pixel conversion and sampling is uniform on the sphere.
    uniform: Option<[f32; 3]>,
}

fn luminance(p: &[f32; 3]) -> f64 {
    0.2126 * p[0] as f64 + 0.7152 * p[1] as f64 + 0.0722 * p[2] as f64
}

impl EnvironmentMap {
    /// Wraps a lat-long image (negative and non-finite pixels are clamped to zero).
    pub fn from_image(mut image: Image) -> Result<Self> {
        for p in image.pixels_mut() {
            for c in p.iter_mut() {
                if !c.is_finite() || *c < 0.0 {
                    *c = 0.0;
                }
            }
        }
        let (w, h) = (image.width(), image.height());
        let mut weights = vec![0.0; w * h];
        for y in 0..h {
            let sin_t = ((y as f64 + 0.5) / h as f64 * PI).sin();
            for x in 0..w {
                // a floor keeps every direction reachable (luminance 0 pixels with colour)
                let p = image.get(x, y);
                let l = luminance(&p).max(1e-3 * (p[0] + p[1] + p[2]) as f64);
                weights[y * w + x] = l * sin_t;
            }
        }
        let first = image.get(0, 0);
        let uniform = image
            .pixels()
            .iter()
            .all(|p| *p == first)
            .then_some(first)
            .filter(|p| p.iter().any(|&c| c > 0.0));
        Ok(Self {
            distribution: Distribution2D::new(&weights, w, h),
            uniform,
            image,
            scale: 1.0,
            rotation: 0.0,
        })
    }

    /// Reads a lat-long OpenEXR light probe.
    pub fn read_exr(path: &Path) -> Result<Self> {
        Self::from_image(Image::read_exr(path)?)
    }

    /// Reads a lat-long light probe, OpenEXR (`.exr`) or Radiance (`.hdr`), by extension.
    pub fn read(path: &Path) -> Result<Self> {
        Self::from_image(Image::read(path)?)
    }

    /// A uniform environment of radiance `rgb` (a 32 × 16 map).
    pub fn constant(rgb: Rgb) -> Result<Self> {
        if rgb.iter().any(|c| !c.is_finite() || *c < 0.0) {
            return Err(RenderError::InvalidArgument(format!(
                "constant environment radiance {rgb:?}"
            )));
        }
        let px = [rgb[0] as f32, rgb[1] as f32, rgb[2] as f32];
        Self::from_image(Image::from_pixels(32, 16, vec![px; 32 * 16])?)
    }

    /// A procedural outdoor-like light probe: sky gradient, dark ground, a small bright sun
    /// and a few seeded rectangular "windows". Useful when no measured probe is at hand.
    pub fn procedural_probe(width: usize, height: usize, seed: u64) -> Result<Self> {
        let mut img = Image::new(width, height)?;
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed);
        let sun = direction_from_uv(0.15, 0.30);
        let sun_cos = (2.5f64).to_radians().cos();
        let windows: Vec<(f64, f64, f64, f64, [f64; 3])> = (0..4)
            .map(|_| {
                let u = rng.gen_range(0.0..1.0);
                let v = rng.gen_range(0.15..0.45);
                let du = rng.gen_range(0.02..0.06);
                let dv = rng.gen_range(0.03..0.08);
                let warm = rng.gen_range(0.0..1.0);
                let k = rng.gen_range(4.0..12.0);
                (
                    u,
                    v,
                    du,
                    dv,
                    [k, k * (0.85 + 0.1 * warm), k * (0.7 + 0.3 * (1.0 - warm))],
                )
            })
            .collect();
        for y in 0..height {
            let v = (y as f64 + 0.5) / height as f64;
            for x in 0..width {
                let u = (x as f64 + 0.5) / width as f64;
                let d = direction_from_uv(u, v);
                let mut c = if d.y >= 0.0 {
                    let t = d.y.sqrt();
                    [0.9 - 0.6 * t, 0.95 - 0.45 * t, 1.0 - 0.1 * t].map(|x| x * 0.8)
                } else {
                    let checker = (((u * 48.0) as i64 + (v * 24.0) as i64) % 2) as f64;
                    [0.22, 0.18, 0.14].map(|x| x * (0.8 + 0.4 * checker))
                };
                if d.dot(&sun) > sun_cos {
                    c = [600.0, 560.0, 480.0];
                }
                for &(wu, wv, du, dv, col) in &windows {
                    let mut ddu = (u - wu).abs();
                    ddu = ddu.min(1.0 - ddu);
                    if ddu < du && (v - wv).abs() < dv {
                        c = col;
                    }
                }
                img.set(x, y, c.map(|x| x as f32));
            }
        }
        Self::from_image(img)
    }

    /// Multiplies the radiance by `scale`.
    pub fn with_scale(mut self, scale: f64) -> Self {
        self.scale = if scale.is_finite() && scale >= 0.0 {
            scale
        } else {
            1.0
        };
        self
    }

    /// Rotates the map about +y by `degrees`.
    pub fn with_rotation_degrees(mut self, degrees: f64) -> Self {
        self.rotation = if degrees.is_finite() {
            degrees.to_radians()
        } else {
            0.0
        };
        self
    }

    /// The underlying lat-long image.
    pub fn image(&self) -> &Image {
        &self.image
    }

    fn to_map(&self, d: &Vec3) -> Vec3 {
        let (s, c) = (-self.rotation).sin_cos();
        Vec3::new(c * d.x + s * d.z, d.y, -s * d.x + c * d.z)
    }

    fn map_to_world(&self, d: &Vec3) -> Vec3 {
        let (s, c) = self.rotation.sin_cos();
        Vec3::new(c * d.x + s * d.z, d.y, -s * d.x + c * d.z)
    }

    /// Radiance arriving from world direction `d` (travelling towards the scene along −d).
    pub fn radiance(&self, d: &Vec3) -> Rgb {
        if let Some(p) = self.uniform {
            return p.map(|c| c as f64 * self.scale);
        }
        let [u, v] = uv_from_direction(&self.to_map(d));
        let (w, h) = (self.image.width(), self.image.height());
        let x = ((u * w as f64) as usize).min(w - 1);
        let y = ((v * h as f64) as usize).min(h - 1);
        let p = self.image.get(x, y);
        [p[0], p[1], p[2]].map(|c| c as f64 * self.scale)
    }

    /// Solid-angle density of [`Self::sample`] for world direction `d`.
    pub fn pdf(&self, d: &Vec3) -> f64 {
        if self.uniform.is_some() {
            return 1.0 / (4.0 * PI);
        }
        let Some(dist) = &self.distribution else {
            return 0.0;
        };
        let [u, v] = uv_from_direction(&self.to_map(d));
        let sin_t = (v * PI).sin();
        if sin_t <= 0.0 {
            return 0.0;
        }
        dist.density(u, v) / (2.0 * PI * PI * sin_t)
    }

    /// Draws a world direction proportionally to luminance; returns direction, radiance, pdf.
    pub fn sample(&self, rng: &mut SampleRng) -> Option<(Vec3, Rgb, f64)> {
        let u1 = uniform(rng);
        let u2 = uniform(rng);
        self.sample_at(u1, u2)
    }

    /// [`Self::sample`] for given uniforms `u1, u2 ∈ [0, 1)`: the luminance-proportional
    /// direction they map to (stratified or low-discrepancy points stay stratified).
    pub fn sample_at(&self, u1: f64, u2: f64) -> Option<(Vec3, Rgb, f64)> {
        if self.uniform.is_some() {
            let z = 1.0 - 2.0 * u1;
            let r = (1.0 - z * z).max(0.0).sqrt();
            let (s, c) = (TAU * u2).sin_cos();
            let d = Vec3::new(r * c, r * s, z);
            return Some((d, self.radiance(&d), 1.0 / (4.0 * PI)));
        }
        let dist = self.distribution.as_ref()?;
        let ([u, v], p_uv) = dist.sample(u1, u2);
        let sin_t = (v * PI).sin();
        if p_uv <= 0.0 || sin_t <= 0.0 {
            return None;
        }
        let d = self.map_to_world(&direction_from_uv(u, v));
        let pdf = p_uv / (2.0 * PI * PI * sin_t);
        Some((d, self.radiance(&d), pdf))
    }

    /// Total power-like integral `∫ L dω` per channel (for tests and normalisation).
    pub fn integral(&self) -> Rgb {
        let (w, h) = (self.image.width(), self.image.height());
        let mut s = [0.0; 3];
        for y in 0..h {
            let t0 = y as f64 / h as f64 * PI;
            let t1 = (y + 1) as f64 / h as f64 * PI;
            let solid = (t0.cos() - t1.cos()) * TAU / w as f64;
            for x in 0..w {
                let p = self.image.get(x, y);
                for c in 0..3 {
                    s[c] += p[c] as f64 * solid * self.scale;
                }
            }
        }
        s
    }
}

/// Unit direction for lat-long coordinates `(u, v) ∈ [0, 1]²`.
pub fn direction_from_uv(u: f64, v: f64) -> Vec3 {
    let theta = v * PI;
    let phi = u * TAU;
    let st = theta.sin();
    Vec3::new(st * phi.sin(), theta.cos(), -st * phi.cos())
}

/// Lat-long coordinates of a (not necessarily unit) direction.
pub fn uv_from_direction(d: &Vec3) -> [f64; 2] {
    let theta = (d.x * d.x + d.z * d.z).sqrt().atan2(d.y);
    let phi = d.x.atan2(-d.z).rem_euclid(TAU);
    [phi / TAU, theta / PI]
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sampling_density_matches_radiance_integral() {
        let env = EnvironmentMap::procedural_probe(64, 32, 3)
            .unwrap()
            .with_rotation_degrees(30.0);
        let mut rng = SampleRng::seed_from_u64(9);
        // E[L/p] over samples = ∫ L dω
        let n = 20_000;
        let mut s = [0.0; 3];
        for _ in 0..n {
            let (d, l, p) = env.sample(&mut rng).unwrap();
            assert!((env.pdf(&d) - p).abs() <= 1e-6 * p);
            assert!((env.radiance(&d)[0] - l[0]).abs() < 1e-9);
            for c in 0..3 {
                s[c] += l[c] / p / n as f64;
            }
        }
        let exact = env.integral();
        for c in 0..3 {
            assert!(
                (s[c] - exact[c]).abs() < 0.02 * exact[c],
                "{s:?} vs {exact:?}"
            );
        }
        // a probe written to OpenEXR reads back as the same light
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("probe.exr");
        let probe = EnvironmentMap::procedural_probe(32, 16, 4).unwrap();
        probe.image().write_exr(&path).unwrap();
        let back = EnvironmentMap::read_exr(&path).unwrap();
        for d in [Vec3::y(), Vec3::new(0.3, -0.2, 0.9).normalize(), -Vec3::x()] {
            assert_eq!(back.radiance(&d), probe.radiance(&d));
            assert!((back.pdf(&d) - probe.pdf(&d)).abs() <= 1e-12 * probe.pdf(&d));
        }
        assert!(EnvironmentMap::constant([f64::NAN, 0.0, 0.0]).is_err());
        let [u, v] = uv_from_direction(&direction_from_uv(0.3, 0.7));
        assert!((u - 0.3).abs() < 1e-12 && (v - 0.7).abs() < 1e-12);
    }

    #[test]
    fn a_constant_environment_is_sampled_uniformly_on_the_sphere() {
        let l = [0.5, 1.0, 2.0];
        let env = EnvironmentMap::constant(l).unwrap().with_scale(2.0);
        let exact = env.integral();
        let mut rng = SampleRng::seed_from_u64(4);
        let n = 40_000;
        let (mut mean, mut upper) = (Vec3::zeros(), 0usize);
        for _ in 0..n {
            let (d, radiance, p) = env.sample(&mut rng).unwrap();
            assert!((d.norm() - 1.0).abs() < 1e-12);
            assert_eq!(p, env.pdf(&d));
            for c in 0..3 {
                // every sample's L / p is the whole integral: no variance
                assert!((radiance[c] / p - exact[c]).abs() < 1e-9 * exact[c]);
            }
            mean += d / n as f64;
            upper += usize::from(d.y > 0.0);
        }
        assert!(mean.norm() < 0.02, "mean direction {mean:?}");
        assert!((upper as f64 / n as f64 - 0.5).abs() < 0.01);
        // the constant, scaled, from every direction
        let d = Vec3::new(0.2, 0.5, -0.8).normalize();
        assert_eq!(env.radiance(&d), [1.0, 2.0, 4.0]);
        // black: nothing to sample
        let black = EnvironmentMap::constant([0.0; 3]).unwrap();
        assert!(black.sample(&mut rng).is_none());
        assert_eq!(black.pdf(&d), 0.0);
    }
}
