//! What the page shows, computed from any `Brdf`, and the images sent as PNG.

use crate::error::{Result, ServeError};
use brdf::{bin_angles, bin_coords, THETA_D_RES, THETA_H_RES};
use brdf::{Brdf, HalfDiff, Vec3};
use rayon::prelude::*;
use serde::Serialize;
use std::collections::HashMap;
use std::sync::{Arc, Mutex};
use traits::SpherePreview;

/// Largest image side served.
pub const MAX_SIZE: usize = 512;

/// Linear RGB pixels of a square image.
pub type Pixels = Vec<[f32; 3]>;

/// A light direction from the page's `(lx, ly)` (the point of the sphere the light is over,
/// in the unit disc); `z` is the rest of the unit vector (a point outside the disc is pulled
/// onto its rim, a grazing light).
pub fn light_direction(lx: f64, ly: f64) -> Result<[f64; 3]> {
    if !lx.is_finite() || !ly.is_finite() {
        return Err(ServeError::InvalidParameter(
            "light direction not finite".into(),
        ));
    }
    let r2 = lx * lx + ly * ly;
    if r2 > 1.0 {
        let r = r2.sqrt();
        return Ok([lx / r, ly / r, 0.0]);
    }
    Ok([lx, ly, (1.0 - r2).sqrt()])
}

/// Checks an image side.
pub fn check_size(size: usize) -> Result<usize> {
    if (8..=MAX_SIZE).contains(&size) {
        Ok(size)
    } else {
        Err(ServeError::InvalidParameter(format!(
            "size {size} (8 to {MAX_SIZE} pixels)"
        )))
    }
}

/// Key of a kept preview: size and the quantised light position.
type PreviewKey = (usize, [i32; 2]);

/// Sphere previews kept by size and light direction (building one is a pass over its pixels).
///
/// The page's views are computed from any [`Brdf`]: the lit sphere (the bins of
/// [`traits::SpherePreview`]), the [`IncidencePlane`] cut, the θh × θd [`Slice`], the
/// [`AlbedoCurve`], the [`Comparison`] of two spheres, and environment-map renders through
/// `render`'s path tracer. Images are tone-mapped here and sent as PNG.
#[derive(Default)]
pub struct PreviewCache {
    map: Mutex<HashMap<PreviewKey, Arc<SpherePreview>>>,
}

impl PreviewCache {
    /// The preview of a `size²` sphere lit from `(lx, ly)` (quantised to 1/2000).
    pub fn get(&self, size: usize, lx: f64, ly: f64) -> Result<Arc<SpherePreview>> {
        let size = check_size(size)?;
        let key = (
            size,
            [(lx * 2000.0).round() as i32, (ly * 2000.0).round() as i32],
        );
        if let Some(p) = crate::library::lock(&self.map).get(&key) {
            return Ok(p.clone());
        }
        let l = light_direction(key.1[0] as f64 / 2000.0, key.1[1] as f64 / 2000.0)?;
        let p = Arc::new(SpherePreview::new(size, l));
        let mut m = crate::library::lock(&self.map);
        if m.len() > 64 {
            m.clear();
        }
        m.insert(key, p.clone());
        Ok(p)
    }
}

/// The BRDF at a bin's grid angles (φh = 0).
fn at_bin(b: &dyn Brdf, bin: usize) -> [f64; 3] {
    let (i, j, k) = bin_coords(bin);
    let (theta_h, theta_d, phi_d) = bin_angles(i, j, k);
    b.eval_half_diff(&HalfDiff {
        theta_h,
        phi_h: 0.0,
        theta_d,
        phi_d,
    })
}

/// The lit sphere of any BRDF: `f · cos θi` at the preview's bins. A table's own bin values
/// are read ([`SpherePreview::shade_table`], the same as an edit session's preview); other
/// BRDFs are evaluated at the bins' grid angles.
pub fn sphere(b: &dyn Brdf, table: Option<&brdf::MerlTable>, p: &SpherePreview) -> Pixels {
    if let Some(t) = table {
        return p.shade_table(t);
    }
    let vals: Vec<(usize, [f32; 3])> = p
        .pixels
        .par_iter()
        .map(|&(px, bin, cos)| {
            let f = at_bin(b, bin);
            (
                px,
                [
                    (f[0].max(0.0) as f32) * cos,
                    (f[1].max(0.0) as f32) * cos,
                    (f[2].max(0.0) as f32) * cos,
                ],
            )
        })
        .collect();
    let mut img = vec![[0.0f32; 3]; p.size * p.size];
    for (px, v) in vals {
        img[px] = v;
    }
    img
}

/// Tone-maps linear pixels (`× 2^exposure`, clipped, sRGB) and encodes them as PNG.
pub fn png(
    pixels: &[[f32; 3]],
    width: usize,
    height: usize,
    exposure_stops: f64,
) -> Result<Vec<u8>> {
    if !exposure_stops.is_finite() || exposure_stops.abs() > 30.0 {
        return Err(ServeError::InvalidParameter(format!(
            "exposure {exposure_stops} (−30 to 30 stops)"
        )));
    }
    let img = render::Image::from_pixels(width, height, pixels.to_vec())?;
    let bytes = img.to_srgb8(&render::Tonemap {
        exposure: exposure_stops.exp2(),
        operator: render::TonemapOperator::Clamp,
    });
    png_rgb8(&bytes, width, height)
}

/// Encodes 8-bit RGB bytes as PNG (fast compression: the images are regenerated on demand).
pub fn png_rgb8(bytes: &[u8], width: usize, height: usize) -> Result<Vec<u8>> {
    use image::codecs::png::{CompressionType, FilterType, PngEncoder};
    use image::ImageEncoder;
    let mut out = Vec::with_capacity(bytes.len() / 2);
    PngEncoder::new_with_quality(&mut out, CompressionType::Fast, FilterType::Sub)
        .write_image(
            bytes,
            width as u32,
            height as u32,
            image::ExtendedColorType::Rgb8,
        )
        .map_err(|e| ServeError::Png(e.to_string()))?;
    Ok(out)
}

/// The BRDF in the plane of incidence: `ωi` at `θi` (φi = 0) and `ωo` swept through the same
/// plane from −90° (beside the light) to +90° (the mirror side).
#[derive(Debug, Clone, Serialize)]
pub struct IncidencePlane {
    /// Incidence angle, degrees.
    pub theta_i_deg: f64,
    /// Signed outgoing angles, degrees (positive = the side of the mirror direction).
    pub theta_o_deg: Vec<f64>,
    /// BRDF (1/sr) per outgoing angle, RGB.
    pub rgb: Vec<[f64; 3]>,
}

/// [`IncidencePlane`] with `n` outgoing angles.
pub fn incidence_plane(b: &dyn Brdf, theta_i_deg: f64, n: usize) -> Result<IncidencePlane> {
    if !(0.0..=89.0).contains(&theta_i_deg) || !(3..=2000).contains(&n) {
        return Err(ServeError::InvalidParameter(format!(
            "theta_i {theta_i_deg}° (0 to 89) or {n} samples"
        )));
    }
    let ti = theta_i_deg.to_radians();
    let wi = Vec3::new(-ti.sin(), 0.0, ti.cos());
    let theta_o_deg: Vec<f64> = (0..n)
        .map(|k| -89.5 + 179.0 * k as f64 / (n - 1) as f64)
        .collect();
    let rgb = theta_o_deg
        .par_iter()
        .map(|&t| {
            let to = t.to_radians();
            let wo = Vec3::new(to.sin(), 0.0, to.cos());
            let f = b.eval(&wi, &wo);
            [f[0].max(0.0), f[1].max(0.0), f[2].max(0.0)]
        })
        .collect();
    Ok(IncidencePlane {
        theta_i_deg,
        theta_o_deg,
        rgb,
    })
}

/// The BRDF on the MERL grid's θh × θd nodes at one φd.
#[derive(Debug, Clone, Serialize)]
pub struct Slice {
    /// The difference azimuth, degrees.
    pub phi_d_deg: f64,
    /// θh of the columns, degrees (square-root spacing of the MERL grid).
    pub theta_h_deg: Vec<f64>,
    /// θd of the rows, degrees.
    pub theta_d_deg: Vec<f64>,
    /// Row-major `θd × θh` RGB values (1/sr).
    pub rgb: Vec<[f32; 3]>,
}

/// [`Slice`] of `b` at `phi_d_deg`.
pub fn slice(b: &dyn Brdf, phi_d_deg: f64) -> Result<Slice> {
    if !(0.0..=180.0).contains(&phi_d_deg) {
        return Err(ServeError::InvalidParameter(format!(
            "phi_d {phi_d_deg}° (0 to 180)"
        )));
    }
    let phi_d = phi_d_deg.to_radians();
    let theta_h: Vec<f64> = (0..THETA_H_RES).map(|i| bin_angles(i, 0, 0).0).collect();
    let theta_d: Vec<f64> = (0..THETA_D_RES).map(|j| bin_angles(0, j, 0).1).collect();
    let rgb = (0..THETA_D_RES * THETA_H_RES)
        .into_par_iter()
        .map(|k| {
            let (j, i) = (k / THETA_H_RES, k % THETA_H_RES);
            let f = b.eval_half_diff(&HalfDiff {
                theta_h: theta_h[i],
                phi_h: 0.0,
                theta_d: theta_d[j],
                phi_d,
            });
            [
                f[0].max(0.0) as f32,
                f[1].max(0.0) as f32,
                f[2].max(0.0) as f32,
            ]
        })
        .collect();
    Ok(Slice {
        phi_d_deg,
        theta_h_deg: theta_h.iter().map(|t| t.to_degrees()).collect(),
        theta_d_deg: theta_d.iter().map(|t| t.to_degrees()).collect(),
        rgb,
    })
}

/// Directional albedo against the incidence angle.
#[derive(Debug, Clone, Serialize)]
pub struct AlbedoCurve {
    /// Incidence angles, degrees.
    pub theta_i_deg: Vec<f64>,
    /// Albedo per angle, RGB ([`brdf::directional_albedo`], 48 × 48 cells).
    pub albedo: Vec<[f64; 3]>,
}

/// [`AlbedoCurve`] at θi = 0, 5, …, 85°.
pub fn albedo(b: &dyn Brdf) -> AlbedoCurve {
    let theta_i_deg: Vec<f64> = (0..18).map(|k| 5.0 * k as f64).collect();
    let albedo = theta_i_deg
        .par_iter()
        .map(|t| brdf::directional_albedo(b, t.to_radians(), 48, 48))
        .collect();
    AlbedoCurve {
        theta_i_deg,
        albedo,
    }
}

/// A comparison of two sphere images.
#[derive(Debug, Clone, Serialize)]
pub struct Comparison {
    /// RMS over lit pixels and channels of `ln(1 + a) − ln(1 + b)` (log-radiance difference).
    pub rms_log: f64,
    /// Largest absolute radiance difference.
    pub max_abs: f64,
    /// Relative RMS difference `‖a − b‖ / ‖a‖` over the lit pixels.
    pub relative: f64,
}

/// The difference image `|a − b|` (channel mean) in a false-colour ramp scaled to its own
/// maximum, as 8-bit RGB, and its summary.
pub fn difference(a: &[[f32; 3]], b: &[[f32; 3]]) -> (Vec<u8>, Comparison) {
    let d: Vec<f32> = a
        .iter()
        .zip(b)
        .map(|(p, q)| ((p[0] - q[0]).abs() + (p[1] - q[1]).abs() + (p[2] - q[2]).abs()) / 3.0)
        .collect();
    let max = d.iter().copied().fold(0.0f32, f32::max);
    let (mut s2, mut n, mut num, mut den) = (0.0f64, 0usize, 0.0f64, 0.0f64);
    let mut max_abs = 0.0f64;
    for (p, q) in a.iter().zip(b) {
        if p.iter().chain(q).all(|v| *v == 0.0) {
            continue;
        }
        for c in 0..3 {
            let (x, y) = (p[c] as f64, q[c] as f64);
            s2 += ((1.0 + x).ln() - (1.0 + y).ln()).powi(2);
            num += (x - y).powi(2);
            den += x * x;
            max_abs = max_abs.max((x - y).abs());
            n += 1;
        }
    }
    let mut rgb = Vec::with_capacity(d.len() * 3);
    for v in d {
        let t = if max > 0.0 { (v / max) as f64 } else { 0.0 };
        rgb.extend_from_slice(&ramp(t));
    }
    (
        rgb,
        Comparison {
            rms_log: if n > 0 { (s2 / n as f64).sqrt() } else { 0.0 },
            max_abs,
            relative: if den > 0.0 { (num / den).sqrt() } else { 0.0 },
        },
    )
}

/// A perceptually ordered dark-blue → orange → yellow ramp for `t ∈ [0, 1]`.
pub fn ramp(t: f64) -> [u8; 3] {
    const STOPS: [[f64; 3]; 5] = [
        [0.05, 0.03, 0.10],
        [0.25, 0.10, 0.45],
        [0.70, 0.20, 0.40],
        [0.98, 0.55, 0.15],
        [0.99, 0.95, 0.60],
    ];
    let t = t.clamp(0.0, 1.0) * (STOPS.len() - 1) as f64;
    let i = (t.floor() as usize).min(STOPS.len() - 2);
    let f = t - i as f64;
    let mut out = [0u8; 3];
    for c in 0..3 {
        out[c] = ((STOPS[i][c] * (1.0 - f) + STOPS[i + 1][c] * f) * 255.0).round() as u8;
    }
    out
}

/// What stands under the environment map.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Shape {
    /// A unit sphere.
    Sphere,
    /// The Utah teapot.
    Teapot,
}

/// Renders `b` on a sphere or the teapot under `env` by path tracing with `spp` samples per
/// pixel (seeded by `seed`, so a pass is reproducible). The page asks for passes of growing
/// `spp` and shows each as it arrives (progressive refinement).
pub fn environment(
    b: Arc<dyn Brdf>,
    env: &render::EnvironmentMap,
    shape: Shape,
    size: usize,
    spp: u32,
    seed: u64,
) -> Result<Pixels> {
    let size = check_size(size)?;
    if !(1..=1024).contains(&spp) {
        return Err(ServeError::InvalidParameter(format!(
            "spp {spp} (1 to 1024)"
        )));
    }
    let material: render::SurfaceMaterial = render::Material::new(b).into();
    let scene = match shape {
        Shape::Teapot => render::teapot_scene(material, Some(env.clone()), None, size, size)?,
        Shape::Sphere => {
            let camera = render::Camera {
                position: Vec3::new(0.0, 0.0, 4.0),
                look_at: Vec3::zeros(),
                up: Vec3::y(),
                fov_degrees: 32.0,
                width: size,
                height: size,
            };
            let mut sb = render::SceneBuilder::new(camera);
            let m = sb.add_material(material);
            sb.add_sphere(Vec3::zeros(), 1.0, m)?;
            sb.set_environment(env.clone());
            sb.build()?
        }
    };
    let options = render::RenderOptions {
        spp,
        seed,
        max_depth: if shape == Shape::Sphere { 2 } else { 3 },
        ..Default::default()
    };
    let img = render::render_scene(&scene, &options)?;
    Ok(img.pixels().to_vec())
}

/// The θh × θd slice as an 8-bit false-colour image (log scale over the slice's range), for
/// the exported PNG of the slice view.
pub fn slice_image(s: &Slice) -> Vec<u8> {
    let lum: Vec<f64> = s
        .rgb
        .iter()
        .map(|p| ((p[0] + p[1] + p[2]) as f64 / 3.0 + 1e-4).ln())
        .collect();
    let lo = lum.iter().copied().fold(f64::INFINITY, f64::min);
    let hi = lum.iter().copied().fold(f64::NEG_INFINITY, f64::max);
    let mut out = Vec::with_capacity(lum.len() * 3);
    for v in lum {
        out.extend_from_slice(&ramp(if hi > lo { (v - lo) / (hi - lo) } else { 0.0 }));
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use brdf::analytic::{Ggx, Lambert};
    use brdf::MerlTable;

    #[test]
    fn sphere_of_a_table_is_the_preview_of_the_table() {
        let g = Ggx {
            kd: [0.2, 0.1, 0.05],
            ks: [0.4; 3],
            alpha: 0.15,
            ior: 1.5,
        };
        let t = MerlTable::tabulate(&g);
        let p = SpherePreview::new(48, light_direction(0.3, 0.2).unwrap());
        let ours = sphere(&t, Some(&t), &p);
        let theirs = p.shade_table(&t);
        for (a, b) in ours.iter().zip(&theirs) {
            for c in 0..3 {
                assert!((a[c] - b[c]).abs() <= 1e-6 * (1.0 + b[c].abs()));
            }
        }
    }

    #[test]
    fn lambertian_views_follow_the_closed_forms() {
        let kd = [0.6, 0.3, 0.15];
        let l = Lambert { kd };
        // Incidence plane: constant kd/π everywhere.
        let ip = incidence_plane(&l, 30.0, 31).unwrap();
        for v in &ip.rgb {
            for c in 0..3 {
                assert!((v[c] - kd[c] / std::f64::consts::PI).abs() < 1e-9);
            }
        }
        // Albedo: kd at every angle (the quadrature integrates a constant exactly up to
        // the grid's cosine sum).
        let a = albedo(&l);
        for row in &a.albedo {
            for c in 0..3 {
                assert!((row[c] - kd[c]).abs() < 2e-2 * kd[c], "{row:?}");
            }
        }
        // Slice: constant too.
        let s = slice(&l, 90.0).unwrap();
        assert_eq!(s.rgb.len(), THETA_H_RES * THETA_D_RES);
        assert!(s
            .rgb
            .iter()
            .all(|p| (p[1] as f64 - kd[1] / std::f64::consts::PI).abs() < 1e-6));
        // Sphere under a head-on light: pixel value kd/π · cos θ, the centre brightest.
        let p = SpherePreview::new(32, light_direction(0.0, 0.0).unwrap());
        let img = sphere(&l, None, &p);
        let centre = img[16 * 32 + 16][0];
        let edge = img[16 * 32 + 1][0];
        assert!(centre > edge && edge > 0.0);
        assert!((centre as f64 - kd[0] / std::f64::consts::PI).abs() < 0.01);
    }

    #[test]
    fn glossier_ggx_has_a_higher_narrower_peak_in_the_incidence_plane() {
        let mk = |alpha| Ggx {
            kd: [0.05; 3],
            ks: [0.5; 3],
            alpha,
            ior: 1.5,
        };
        let (rough, gloss) = (mk(0.3), mk(0.08));
        let a = incidence_plane(&rough, 30.0, 359).unwrap();
        let b = incidence_plane(&gloss, 30.0, 359).unwrap();
        let peak = |p: &IncidencePlane| {
            let (k, v) = p
                .rgb
                .iter()
                .enumerate()
                .map(|(k, v)| (k, v[0]))
                .fold((0, 0.0), |m, x| if x.1 > m.1 { x } else { m });
            let width = p.rgb.iter().filter(|v| v[0] > 0.5 * p.rgb[k][0]).count();
            (p.theta_o_deg[k], v, width)
        };
        let (ta, va, wa) = peak(&a);
        let (tb, vb, wb) = peak(&b);
        // Both peak near the mirror direction (+30°; the rough one off-specular, further out),
        // the glossier one higher and narrower.
        assert!(
            (tb - 30.0).abs() < 2.0 && (ta - 30.0).abs() < 10.0,
            "{ta} {tb}"
        );
        assert!(vb > 2.0 * va && wb < wa, "{va} {vb} {wa} {wb}");
    }

    #[test]
    fn difference_of_equal_images_is_zero_and_grows_with_the_change() {
        let a = vec![[0.5f32, 0.4, 0.3]; 16];
        let (_, same) = difference(&a, &a);
        assert_eq!(same.rms_log, 0.0);
        let b: Vec<[f32; 3]> = a.iter().map(|p| [p[0] * 1.1, p[1], p[2]]).collect();
        let c: Vec<[f32; 3]> = a.iter().map(|p| [p[0] * 1.5, p[1], p[2]]).collect();
        let (_, small) = difference(&a, &b);
        let (_, big) = difference(&a, &c);
        assert!(small.rms_log > 0.0 && big.rms_log > small.rms_log);
        assert!((small.max_abs - 0.05).abs() < 1e-6);
    }

    #[test]
    fn png_round_trips_through_the_decoder() {
        let px = vec![[0.25f32, 0.5, 1.0]; 64];
        let bytes = png(&px, 8, 8, 0.0).unwrap();
        let img = image::load_from_memory(&bytes).unwrap().to_rgb8();
        assert_eq!(img.dimensions(), (8, 8));
        let p = img.get_pixel(3, 3).0;
        let enc = |x: f64| (render::srgb_encode(x) * 255.0 + 0.5) as u8;
        assert_eq!(p, [enc(0.25), enc(0.5), 255]);
        assert!(png(&px, 8, 8, f64::NAN).is_err());
    }
}
