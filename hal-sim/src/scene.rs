//! The physically based scene and sensor model behind the simulated devices.

use crate::config::SimConfig;
use crate::rng::{frame_key, word, PixelStream};
use crate::truth::{CameraIntrinsics, CameraPose, SceneTruth};
use crate::SimError;
use brdf::Brdf;
use gantry_hal::BayerPattern;
use nalgebra::Vector3;
use rayon::prelude::*;
use std::sync::Arc;

/// Streams of the counter-based generator (one per purpose).
const STREAM_PRNU: u64 = 0x5052_4E55;
const STREAM_DARK: u64 = 0x4441_524B;
const STREAM_HOT: u64 = 0x484F_5421;

/// Geometry of one camera pixel whose centre ray hits the sphere.
#[derive(Debug, Clone, Copy)]
struct SphereHit {
    pixel: u32,
    point: Vector3<f64>,
    normal: Vector3<f64>,
    tangent: Vector3<f64>,
    bitangent: Vector3<f64>,
    /// Direction to the camera in the local frame.
    wo_local: Vector3<f64>,
}

/// Noise-free ground truth for one lamp position.
#[derive(Debug, Clone, PartialEq)]
pub struct PositionTruth {
    /// Lamp angle, degrees.
    pub angle_deg: f64,
    /// Radiance reaching each photosite through its own colour filter (sphere + stray floor),
    /// W m⁻² sr⁻¹, row-major.
    pub radiance: Vec<f32>,
    /// Expected signal growth of each photosite, DN per second (light, PRNU and dark current
    /// at the operating temperature; before quantisation and saturation).
    pub signal_rate_dn_per_s: Vec<f32>,
    /// Whether the pixel's centre ray hits the sphere.
    pub on_sphere: Vec<bool>,
}

/// The scene: camera, sphere, lamp, room and sensor, with the per-pixel fixed patterns.
///
/// It renders the sphere's radiance under the lamp (inverse-square falloff and foreshortening)
/// over the stray-light floor of the room, seen through a pinhole camera with radial
/// distortion, and turns it into raw samples of an RGGB sensor with shot, read and dark noise,
/// PRNU, hot pixels, gain, black level, 10-bit quantisation and saturation. [`SimRig::scene`]
/// gives the scene of a rig.
///
/// [`SimRig::scene`]: crate::SimRig::scene
pub struct Scene {
    truth: SceneTruth,
    brdf: Arc<dyn Brdf>,
    pattern: BayerPattern,
    hits: Vec<SphereHit>,
    /// Per-pixel relative gain (PRNU), mean 1.
    prnu: Vec<f32>,
    /// Per-pixel dark current at the reference temperature, electrons per second.
    dark_ref: Vec<f32>,
    hot: Vec<(usize, usize)>,
    seed: u64,
}

impl std::fmt::Debug for Scene {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Scene")
            .field("camera", &self.truth.camera)
            .field("material", &self.truth.material)
            .field("sphere_pixels", &self.hits.len())
            .finish_non_exhaustive()
    }
}

fn check_finite(what: &str, xs: &[f64]) -> Result<(), SimError> {
    if xs.iter().all(|x| x.is_finite()) {
        Ok(())
    } else {
        Err(SimError::Config(format!("{what} must be finite")))
    }
}

impl Scene {
    /// Builds the scene of `cfg` with the sample material `brdf`.
    pub fn new(cfg: &SimConfig, brdf: Arc<dyn Brdf>) -> Result<Self, SimError> {
        if !(cfg.scale > 0.0 && cfg.scale <= 4.0) {
            return Err(SimError::Config(format!(
                "scale {} not in (0, 4]",
                cfg.scale
            )));
        }
        let c = &cfg.camera;
        check_finite("camera", &[c.fx, c.fy, c.cx, c.cy, c.k1, c.k2])?;
        if c.fx <= 0.0 || c.fy <= 0.0 || c.width < 2 || c.height < 2 {
            return Err(SimError::Config(
                "camera size and focal lengths must be positive".into(),
            ));
        }
        check_finite("sphere", &[cfg.sphere.radius])?;
        if cfg.sphere.radius <= 0.0 || cfg.lamp.circle.radius <= cfg.sphere.radius {
            return Err(SimError::Config(
                "sphere radius must be positive and smaller than the lamp circle".into(),
            ));
        }
        let s = &cfg.sensor;
        if s.bit_depth == 0 || s.bit_depth > 16 || s.gain_e_per_dn <= 0.0 || s.full_well_e <= 0.0 {
            return Err(SimError::Config("sensor bit depth, gain, full well".into()));
        }
        let n = Vector3::from(cfg.lamp.circle.normal);
        let u = Vector3::from(cfg.lamp.circle.reference);
        if (n.norm() - 1.0).abs() > 1e-6 || (u.norm() - 1.0).abs() > 1e-6 || n.dot(&u).abs() > 1e-6
        {
            return Err(SimError::Config(
                "lamp circle normal and reference must be orthonormal".into(),
            ));
        }
        let camera = cfg.camera.scaled(cfg.scale);
        let pose = cfg.pose();
        let truth = SceneTruth {
            camera,
            pose,
            lamp: cfg.lamp,
            sphere: cfg.sphere,
            sensor: cfg.sensor.clone(),
            stray_radiance: cfg.stray_radiance,
            material: brdf.name(),
        };
        let hits = sphere_hits(&truth.camera, &pose, &truth);
        let npx = camera.width * camera.height;
        let seed = cfg.seed;
        let prnu: Vec<f32> = (0..npx as u64)
            .into_par_iter()
            .map(|i| {
                let mut r = PixelStream::new(seed, STREAM_PRNU, i);
                (1.0 + s.prnu_sigma * r.normal()).max(0.0) as f32
            })
            .collect();
        // Hot pixels: dark signal in a 60 s frame at the operating temperature, log-uniform in
        // the configured DN range; the rest log-normal around the mean dark current.
        let t_factor = s.dark_temperature_factor(s.temperature_c);
        let mut dark_ref: Vec<f32> = (0..npx as u64)
            .into_par_iter()
            .map(|i| {
                let mut r = PixelStream::new(seed, STREAM_DARK, i);
                let sig = s.dark_current_log_sigma;
                (s.dark_current_e_per_s * (sig * r.normal() - 0.5 * sig * sig).exp()) as f32
            })
            .collect();
        let mut hot = Vec::new();
        for (i, d) in dark_ref.iter_mut().enumerate() {
            let mut r = PixelStream::new(seed, STREAM_HOT, i as u64);
            if r.uniform() < s.hot_pixel_fraction {
                let (lo, hi) = (s.hot_pixel_dn_60s[0].max(1e-3), s.hot_pixel_dn_60s[1]);
                let dn = lo * (hi / lo).powf(r.uniform());
                *d = (dn * s.gain_e_per_dn / 60.0 / t_factor) as f32;
            }
        }
        for (i, &d) in dark_ref.iter().enumerate() {
            let dn60 = s.black_level_dn + d as f64 * t_factor * 60.0 / s.gain_e_per_dn;
            if dn60 > 16.0 {
                hot.push((i % camera.width, i / camera.width));
            }
        }
        Ok(Self {
            truth,
            brdf,
            pattern: BayerPattern::Rggb,
            hits,
            prnu,
            dark_ref,
            hot,
            seed: word(seed, 0x5345_4E53, 0),
        })
    }

    /// The ground truth of the scene.
    pub fn truth(&self) -> &SceneTruth {
        &self.truth
    }

    /// The sample's BRDF.
    pub fn brdf(&self) -> &Arc<dyn Brdf> {
        &self.brdf
    }

    /// Colour filter arrangement of the sensor.
    pub fn pattern(&self) -> BayerPattern {
        self.pattern
    }

    /// Sensor columns.
    pub fn width(&self) -> usize {
        self.truth.camera.width
    }

    /// Sensor rows.
    pub fn height(&self) -> usize {
        self.truth.camera.height
    }

    /// Photosites whose noise-free value in a 60 s dark frame at the operating temperature
    /// exceeds 16 DN (column, row), in row-major order.
    pub fn hot_pixels(&self) -> &[(usize, usize)] {
        &self.hot
    }

    /// Number of pixels whose centre ray hits the sphere.
    pub fn sphere_pixel_count(&self) -> usize {
        self.hits.len()
    }

    /// Per-pixel relative gain (photo-response non-uniformity).
    pub fn prnu(&self) -> &[f32] {
        &self.prnu
    }

    /// Radiance image (RGB per pixel, W m⁻² sr⁻¹) with the lamp at `angle_deg` scaled by
    /// `lamp_scale` (0 = off), before defocus blur; `with_stray` adds the room's stray-light
    /// floor.
    pub fn radiance_rgb(&self, angle_deg: f64, lamp_scale: f64, with_stray: bool) -> Vec<[f32; 3]> {
        let t = &self.truth;
        let stray = if with_stray {
            t.stray_radiance.map(|x| x as f32)
        } else {
            [0.0; 3]
        };
        let mut img = vec![stray; t.camera.width * t.camera.height];
        if lamp_scale <= 0.0 {
            return img;
        }
        let lamp_pos = t.lamp.circle.position(angle_deg);
        let a2 = t.lamp.disc_radius * t.lamp.disc_radius;
        let intensity = t.lamp.radiant_intensity.map(|i| i * lamp_scale);
        let brdf = &self.brdf;
        let values: Vec<(u32, [f32; 3])> = self
            .hits
            .par_iter()
            .with_min_len(1024)
            .filter_map(|h| {
                let l = lamp_pos - h.point;
                let d2 = l.norm_squared();
                let wi = l / d2.sqrt();
                let cos_i = wi.dot(&h.normal);
                if cos_i <= 0.0 {
                    return None;
                }
                let wi_local = Vector3::new(wi.dot(&h.tangent), wi.dot(&h.bitangent), cos_i);
                let f = brdf.eval(&wi_local, &h.wo_local);
                let g = cos_i / (d2 + a2);
                let mut out = [0f32; 3];
                for c in 0..3 {
                    let v = f[c] * intensity[c] * g;
                    out[c] = if v.is_finite() {
                        v.max(0.0) as f32
                    } else {
                        0.0
                    } + stray[c];
                }
                Some((h.pixel, out))
            })
            .collect();
        for (p, v) in values {
            img[p as usize] = v;
        }
        img
    }

    /// Applies the configured defocus blur and keeps each photosite's own channel.
    pub fn mosaic(&self, rgb: &[[f32; 3]]) -> Vec<f32> {
        let (w, h) = (self.width(), self.height());
        let sigma = self.truth.sensor.defocus_sigma_px;
        let blurred;
        let src = if sigma > 0.0 {
            blurred = gaussian_blur_rgb(rgb, w, h, sigma);
            &blurred[..]
        } else {
            rgb
        };
        let pattern = self.pattern;
        let mut out = vec![0f32; w * h];
        out.par_chunks_mut(w).enumerate().for_each(|(y, row)| {
            for (x, o) in row.iter_mut().enumerate() {
                *o = src[y * w + x][pattern.channel_at(x, y)];
            }
        });
        out
    }

    /// Photo-electron rate of each photosite (e⁻/s, light only) for a mosaicked radiance image.
    pub fn light_rate_e(&self, radiance_mosaic: &[f32]) -> Vec<f32> {
        let s = &self.truth.sensor;
        let (w, pattern) = (self.width(), self.pattern);
        let k = s.quantum_efficiency.map(|q| (q * s.responsivity) as f32);
        radiance_mosaic
            .par_iter()
            .zip(self.prnu.par_iter())
            .enumerate()
            .map(|(i, (&l, &g))| l * k[pattern.channel_at(i % w, i / w)] * g)
            .collect()
    }

    /// Dark-current rate of each photosite at `temp_c`, electrons per second.
    pub fn dark_rate_e(&self, temp_c: f64) -> Vec<f32> {
        let f = self.truth.sensor.dark_temperature_factor(temp_c) as f32;
        self.dark_ref.iter().map(|d| d * f).collect()
    }

    /// Noise-free ground truth for the lamp at `angle_deg` (full intensity).
    pub fn position_truth(&self, angle_deg: f64) -> PositionTruth {
        let rgb = self.radiance_rgb(angle_deg, 1.0, true);
        let radiance = self.mosaic(&rgb);
        let light = self.light_rate_e(&radiance);
        let s = &self.truth.sensor;
        let dark = self.dark_rate_e(s.temperature_c);
        let g = s.gain_e_per_dn as f32;
        let signal_rate_dn_per_s = light.iter().zip(&dark).map(|(l, d)| (l + d) / g).collect();
        let mut on_sphere = vec![false; radiance.len()];
        for h in &self.hits {
            on_sphere[h.pixel as usize] = true;
        }
        PositionTruth {
            angle_deg,
            radiance,
            signal_rate_dn_per_s,
            on_sphere,
        }
    }

    /// Photo-electron rate (e⁻/s) of the lamp's light alone, lamp at `angle_deg`, full output.
    pub fn lamp_rate_e(&self, angle_deg: f64) -> Vec<f32> {
        self.light_rate_e(&self.mosaic(&self.radiance_rgb(angle_deg, 1.0, false)))
    }

    /// Photo-electron rate (e⁻/s) of the stray-light floor alone.
    pub fn stray_rate_e(&self) -> Vec<f32> {
        self.light_rate_e(&self.mosaic(&self.radiance_rgb(0.0, 0.0, true)))
    }

    /// Simulates one exposure: Poisson photo-electrons and dark electrons, full-well clipping,
    /// Gaussian read noise, gain, black level, rounding and clipping to the bit depth.
    ///
    /// The photo-electron rate of a photosite is `lamp_rate_e · lamp_scale + base_rate_e`
    /// (e⁻/s); `frame_number` keys the counter-based noise, so the same arguments always give
    /// the same samples whatever the number of threads.
    pub fn expose(
        &self,
        lamp_rate_e: &[f32],
        lamp_scale: f64,
        base_rate_e: &[f32],
        exposure_s: f64,
        temp_c: f64,
        frame_number: u64,
    ) -> Result<Vec<u16>, SimError> {
        let npx = self.width() * self.height();
        if lamp_rate_e.len() != npx || base_rate_e.len() != npx {
            return Err(SimError::Dimensions(format!(
                "rate maps of {} and {} pixels for a {npx}-pixel sensor",
                lamp_rate_e.len(),
                base_rate_e.len()
            )));
        }
        if !(exposure_s.is_finite() && exposure_s >= 0.0 && lamp_scale.is_finite()) {
            return Err(SimError::Config(format!(
                "exposure {exposure_s} s, lamp scale {lamp_scale}"
            )));
        }
        let s = &self.truth.sensor;
        let w = self.width();
        let dark_f = s.dark_temperature_factor(temp_c);
        let (gain, read, black, full, max) = (
            s.gain_e_per_dn,
            s.read_noise_e,
            s.black_level_dn,
            s.full_well_e,
            s.max_dn(),
        );
        let seed = self.seed;
        let key = frame_key(seed, frame_number);
        // Whether a full well always reads as the largest sample (6 sigma of read noise).
        let saturates = black + (full - 6.0 * read) / gain >= max;
        let mut out = vec![0u16; npx];
        out.par_chunks_mut(w).enumerate().for_each(|(y, row)| {
            for (x, o) in row.iter_mut().enumerate() {
                let i = y * w + x;
                let rate = lamp_rate_e[i] as f64 * lamp_scale
                    + base_rate_e[i] as f64
                    + self.dark_ref[i] as f64 * dark_f;
                let mean = rate * exposure_s;
                // Far above full well (6 sigma) the photosite is saturated whatever the
                // noise: skip the draws.
                if saturates && mean > full && mean - 6.0 * mean.sqrt() > full {
                    *o = max as u16;
                    continue;
                }
                let mut r = PixelStream::for_pixel(key, i as u64);
                let electrons = r.poisson(mean).min(full);
                let dn = black + (electrons + read * r.normal()) / gain;
                *o = dn.round().clamp(0.0, max) as u16;
            }
        });
        Ok(out)
    }
}

fn sphere_hits(cam: &CameraIntrinsics, pose: &CameraPose, truth: &SceneTruth) -> Vec<SphereHit> {
    let centre = pose.centre();
    let sc = Vector3::from(truth.sphere.centre);
    let r = truth.sphere.radius;
    let w = cam.width;
    (0..cam.height)
        .into_par_iter()
        .flat_map_iter(|y| {
            (0..w).filter_map(move |x| {
                let d = pose.dir_to_world(&cam.ray(x as f64, y as f64));
                let oc = centre - sc;
                let b = oc.dot(&d);
                let c = oc.norm_squared() - r * r;
                let disc = b * b - c;
                if disc <= 0.0 {
                    return None;
                }
                let t = -b - disc.sqrt();
                if t <= 0.0 {
                    return None;
                }
                let point = centre + t * d;
                let normal = (point - sc) / r;
                let helper = if normal.z.abs() < 0.9 {
                    Vector3::z()
                } else {
                    Vector3::x()
                };
                let tangent = helper.cross(&normal).normalize();
                let bitangent = normal.cross(&tangent);
                let wo = -d;
                let wo_local = Vector3::new(wo.dot(&tangent), wo.dot(&bitangent), wo.dot(&normal));
                Some(SphereHit {
                    pixel: (y * w + x) as u32,
                    point,
                    normal,
                    tangent,
                    bitangent,
                    wo_local,
                })
            })
        })
        .collect()
}

/// Separable Gaussian blur of an RGB image (clamped borders).
pub fn gaussian_blur_rgb(img: &[[f32; 3]], w: usize, h: usize, sigma: f64) -> Vec<[f32; 3]> {
    let radius = (3.0 * sigma).ceil() as isize;
    let mut k: Vec<f32> = (-radius..=radius)
        .map(|i| (-(i * i) as f64 / (2.0 * sigma * sigma)).exp() as f32)
        .collect();
    let sum: f32 = k.iter().sum();
    k.iter_mut().for_each(|v| *v /= sum);
    let rows = filter_pass(img, w, h, &k, true);
    filter_pass(&rows, w, h, &k, false)
}

/// One pass of a separable filter with the odd-length kernel `k`, along x (`along_x`) or along
/// y, with clamped borders.
fn filter_pass(src: &[[f32; 3]], w: usize, h: usize, k: &[f32], along_x: bool) -> Vec<[f32; 3]> {
    let radius = (k.len() / 2) as isize;
    let mut out = vec![[0f32; 3]; w * h];
    out.par_chunks_mut(w).enumerate().for_each(|(y, row)| {
        for (x, o) in row.iter_mut().enumerate() {
            let mut acc = [0f32; 3];
            for (j, kv) in k.iter().enumerate() {
                let off = j as isize - radius;
                let p = if along_x {
                    src[y * w + (x as isize + off).clamp(0, w as isize - 1) as usize]
                } else {
                    src[(y as isize + off).clamp(0, h as isize - 1) as usize * w + x]
                };
                for c in 0..3 {
                    acc[c] += kv * p[c];
                }
            }
            *o = acc;
        }
    });
    out
}
