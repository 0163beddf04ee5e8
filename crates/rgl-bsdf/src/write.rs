//! Writing any isotropic BRDF as a `.bsdf` file: the adaptive parameterization of Dupuy &
//! Jakob (2018) computed from the material itself.

use crate::error::{Result, RglError};
use crate::marginal::Marginal2D;
use crate::material::{phi2u, theta2u, u2phi, u2theta};
use crate::tensor::{Field, TensorFile};
use brdf::{Brdf, Vec3};
use rayon::prelude::*;
use std::f64::consts::PI;

/// Sizes and choices of a written file.
#[derive(Debug, Clone, PartialEq)]
pub struct WriteOptions {
    /// Rows and columns of the reflectance and luminance grids in the warped domain (the
    /// paper's files use 32).
    pub resolution: usize,
    /// Rows and columns of each visible-normal distribution grid.
    pub vndf_resolution: usize,
    /// Incident elevations from 0 to [`max_theta_i_deg`](Self::max_theta_i_deg), closer
    /// together towards grazing incidence.
    pub theta_i: usize,
    /// Largest incident elevation (degrees); the renderers use the last slice beyond it.
    pub max_theta_i_deg: f64,
    /// Nodes of the microfacet distribution and projected-area curves along `θ`.
    pub ndf_resolution: usize,
    /// Power iterations that turn back-scattering into a microfacet distribution.
    pub ndf_iterations: usize,
    /// Share of a broad (cosine) distribution mixed into the estimated one, so that the warp
    /// keeps some nodes where the material's sharpest lobe is not (a diffuse base under a
    /// specular peak).
    pub broad_share: f64,
    /// Store the reflectance divided by `D(m) / (4 σ(ωi))` (the `jacobian` flag), which
    /// makes it smoother on the warped grid.
    pub jacobian: bool,
    /// Write a spectral file (`spectra` on 360–830 nm, for pbrt-v4 and Mitsuba's spectral
    /// variants) instead of an RGB one (`rgb`, for Mitsuba's RGB variants): each RGB value is
    /// upsampled by [`rgb_basis`](crate::rgb_basis).
    pub spectral: bool,
    /// Text stored in the `description` field.
    pub description: String,
}

impl Default for WriteOptions {
    fn default() -> Self {
        WriteOptions {
            resolution: 32,
            vndf_resolution: 32,
            theta_i: 16,
            max_theta_i_deg: 88.0,
            ndf_resolution: 64,
            ndf_iterations: 6,
            broad_share: 0.3,
            jacobian: true,
            spectral: false,
            description: String::new(),
        }
    }
}

impl WriteOptions {
    /// Reduced sizes for tests and quick previews (about 1/10 of the default's work).
    pub fn small() -> WriteOptions {
        WriteOptions {
            resolution: 16,
            vndf_resolution: 16,
            theta_i: 8,
            ndf_resolution: 32,
            ..WriteOptions::default()
        }
    }

    fn check(&self) -> Result<()> {
        let bad = |m: &str| Err(RglError::Options(m.into()));
        if !(2..=1024).contains(&self.resolution) || !(2..=1024).contains(&self.vndf_resolution) {
            return bad("grid resolutions must lie in 2..=1024");
        }
        if !(2..=256).contains(&self.theta_i) || !(2..=4096).contains(&self.ndf_resolution) {
            return bad("theta_i must lie in 2..=256 and ndf_resolution in 2..=4096");
        }
        if !(1.0..=89.9).contains(&self.max_theta_i_deg) {
            return bad("max_theta_i_deg must lie in [1, 89.9]");
        }
        if !(0.0..=1.0).contains(&self.broad_share) || self.ndf_iterations > 100 {
            return bad("broad_share must lie in [0, 1] and ndf_iterations ≤ 100");
        }
        Ok(())
    }
}

fn luminance(rgb: [f64; 3]) -> f64 {
    0.2126 * rgb[0] + 0.7152 * rgb[1] + 0.0722 * rgb[2]
}

fn direction(theta: f64, phi: f64) -> Vec3 {
    Vec3::new(
        theta.sin() * phi.cos(),
        theta.sin() * phi.sin(),
        theta.cos(),
    )
}

/// `n` incident elevations from 0 to `max`, spaced so that linear interpolation of `1 / cos θ`
/// between them errs alike near grazing incidence (equal steps of `∫ 2 + √(1 + 2 tan² θ) dθ`,
/// the constant keeping slices near the normal, where the geometry still moves): the renderers
/// blend neighbouring slices linearly in `θi`, and the stored reflectance of a glossy lobe
/// carries that factor, so uniform steps would overshoot badly near grazing incidence.
fn incident_elevations(n: usize, max: f64) -> Vec<f32> {
    let steps = 4096;
    let h = max / steps as f64;
    let mut cumulative = Vec::with_capacity(steps + 1);
    let mut s = 0.0;
    cumulative.push(0.0);
    for k in 0..steps {
        let t = (k as f64 + 0.5) * h;
        s += (2.0 + (1.0 + 2.0 * t.tan().powi(2)).sqrt()) * h;
        cumulative.push(s);
    }
    (0..n)
        .map(|j| {
            let target = s * j as f64 / (n - 1) as f64;
            let k = cumulative.partition_point(|&c| c < target).min(steps);
            let (c0, c1) = (cumulative[k.saturating_sub(1)], cumulative[k]);
            let frac = if c1 > c0 {
                (target - c0) / (c1 - c0)
            } else {
                0.0
            };
            ((k.saturating_sub(1) as f64 + if k == 0 { 0.0 } else { frac }) * h) as f32
        })
        .collect()
}

/// `σ(θ)` for an isotropic distribution given at nodes `u_k = k / (n − 1)` (linear in `u`).
fn projected_area(d: &[f64], theta: f64) -> f64 {
    let (nt, np) = (128, 64);
    let w = direction(theta, 0.0);
    let mut sum = 0.0;
    for a in 0..nt {
        let u = (a as f64 + 0.5) / nt as f64;
        let tm = u2theta(u);
        let dm = interp(d, u);
        for b in 0..np {
            let phi = u2phi((b as f64 + 0.5) / np as f64);
            let c = w.dot(&direction(tm, phi));
            if c > 0.0 {
                sum += dm * c * 2.0 * PI * PI * u * tm.sin();
            }
        }
    }
    sum / (nt * np) as f64
}

/// Linear interpolation of node values `v` (nodes at `k / (n − 1)`) at `u ∈ [0, 1]`.
fn interp(v: &[f64], u: f64) -> f64 {
    let x = u.clamp(0.0, 1.0) * (v.len() - 1) as f64;
    let i = (x as usize).min(v.len() - 2);
    let t = x - i as f64;
    v[i] * (1.0 - t) + v[i + 1] * t
}

/// The microfacet distribution whose visible normals best explain the back-scattering of
/// `material` (the paper's power iteration, `D(ω) ∝ f(ω, ω) cos θ σ(ω)`, with the diffuse
/// floor of the back-scattering taken out), mixed with a broad
/// cosine distribution, normalised so that `σ(0) = 1`.
fn microfacet_distribution(material: &dyn Brdf, opts: &WriteOptions) -> Vec<f64> {
    let n = opts.ndf_resolution;
    let raw: Vec<f64> = (0..n)
        .map(|k| {
            let theta = u2theta(k as f64 / (n - 1) as f64).min(89.5f64.to_radians());
            let w = direction(theta, 0.0);
            luminance(material.eval(&w, &w)).max(0.0)
        })
        .collect();
    // the least back-scattering up to 80° is the diffuse floor: left in, it would flatten the
    // estimated distribution and starve the specular peak of grid nodes (the broad share
    // below covers the diffuse part)
    let floor = raw
        .iter()
        .enumerate()
        .filter(|(k, _)| u2theta(*k as f64 / (n - 1) as f64) <= 80f64.to_radians())
        .map(|(_, &b)| b)
        .fold(f64::INFINITY, f64::min);
    let back: Vec<f64> = raw
        .iter()
        .enumerate()
        .map(|(k, &b)| (b - floor).max(0.0) * u2theta(k as f64 / (n - 1) as f64).cos())
        .collect();
    let broad: Vec<f64> = (0..n)
        .map(|k| u2theta(k as f64 / (n - 1) as f64).cos() / PI)
        .collect();
    let mut d = if back.iter().any(|&b| b > 0.0) {
        back.clone()
    } else {
        broad.clone()
    };
    let normalise = |d: &mut Vec<f64>| {
        let s = projected_area(d, 0.0);
        if s > 0.0 {
            d.iter_mut().for_each(|v| *v /= s);
        }
    };
    normalise(&mut d);
    for _ in 0..opts.ndf_iterations {
        let sigma: Vec<f64> = (0..n)
            .map(|k| projected_area(&d, u2theta(k as f64 / (n - 1) as f64)))
            .collect();
        let next: Vec<f64> = back.iter().zip(&sigma).map(|(b, s)| b * s).collect();
        if next.iter().all(|&v| v <= 0.0) {
            break;
        }
        d = next;
        normalise(&mut d);
    }
    let mut mixed: Vec<f64> = d
        .iter()
        .zip(&broad)
        .map(|(a, b)| (1.0 - opts.broad_share) * a + opts.broad_share * b)
        .collect();
    normalise(&mut mixed);
    mixed
}

/// Writes `material` (isotropic) as a `.bsdf` tensor file (RGB, or spectral with
/// [`WriteOptions::spectral`]): the microfacet distribution
/// estimated from its back-scattering, the projected areas, one visible-normal distribution
/// per incident elevation, and `f cos θo` sampled at the nodes of the warped grid (divided by
/// `D / 4σ` with the `jacobian` flag), with luminance tables for importance sampling.
///
/// # Examples
///
/// ```
/// use rgl_bsdf::{RglBsdf, WriteOptions};
///
/// let ggx = brdf::load("ggx:alpha=0.3,kd=0.2").unwrap();
/// let file = rgl_bsdf::write(ggx.as_brdf(), &WriteOptions::small()).unwrap();
/// assert_eq!(file.field("rgb").unwrap().shape, vec![1, 8, 3, 16, 16]);
/// let back = RglBsdf::from_tensor(&rgl_bsdf::TensorFile::parse(&file.to_bytes()).unwrap()).unwrap();
/// assert_eq!(back.resolution(), [1, 8, 16, 16]);
/// ```
pub fn write(material: &dyn Brdf, opts: &WriteOptions) -> Result<TensorFile> {
    opts.check()?;
    let (r, rv, nt, nn) = (
        opts.resolution,
        opts.vndf_resolution,
        opts.theta_i,
        opts.ndf_resolution,
    );
    let d = microfacet_distribution(material, opts);
    let sigma: Vec<f64> = (0..nn)
        .map(|k| projected_area(&d, u2theta(k as f64 / (nn - 1) as f64)))
        .collect();
    let theta_i = incident_elevations(nt, opts.max_theta_i_deg.to_radians());
    // two identical rows: the distributions do not depend on azimuth
    let rows2 = |v: &[f64]| -> Vec<f32> { v.iter().chain(v).map(|&x| x as f32).collect() };
    let ndf_grid = rows2(&d);
    let sigma_grid = rows2(&sigma);
    let ndf = Marginal2D::new(&ndf_grid, nn, 2, vec![], false, false);
    let sigma_i = Marginal2D::new(&sigma_grid, nn, 2, vec![], false, false);

    let mut vndf = vec![0f32; nt * rv * rv];
    for (j, slice) in vndf.chunks_mut(rv * rv).enumerate() {
        let wi = direction(theta_i[j] as f64, 0.0);
        for b in 0..rv {
            let phi = u2phi(b as f64 / (rv - 1) as f64);
            for a in 0..rv {
                let u = a as f64 / (rv - 1) as f64;
                let tm = u2theta(u);
                let c = wi.dot(&direction(tm, phi)).max(0.0);
                slice[b * rv + a] = (interp(&d, u) * c * 2.0 * PI * PI * u * tm.sin()) as f32;
            }
        }
        if slice.iter().all(|&v| v == 0.0) {
            slice.fill(1.0);
        }
    }
    let params = vec![vec![0.0f32], theta_i.clone()];
    let warp = Marginal2D::new(&vndf, rv, rv, params, true, true);

    let slices: Vec<(Vec<f32>, Vec<f32>)> = (0..nt)
        .into_par_iter()
        .map(|j| {
            let ti = theta_i[j] as f64;
            let wi = direction(ti, 0.0);
            let scale_i = 4.0 * sigma_i.eval([theta2u(ti), phi2u(0.0)], &[]);
            let mut rgb = vec![0f32; 3 * r * r];
            let mut lum = vec![0f32; r * r];
            for b in 0..r {
                for a in 0..r {
                    let s = [a as f64 / (r - 1) as f64, b as f64 / (r - 1) as f64];
                    let (u_m, _) = warp.sample(s, &[0.0, ti]);
                    let m = direction(u2theta(u_m[0]), u2phi(u_m[1]));
                    let wo = m * (2.0 * m.dot(&wi)) - wi;
                    if wo.z <= 0.0 {
                        continue;
                    }
                    let wo = wo.normalize();
                    let f = material.eval(&wi, &wo);
                    let scale = if opts.jacobian {
                        let dm = ndf.eval(u_m, &[]);
                        if dm <= 0.0 {
                            continue;
                        }
                        scale_i / dm
                    } else {
                        1.0
                    };
                    let v = f.map(|c| (c.max(0.0) * wo.z * scale) as f32);
                    for c in 0..3 {
                        rgb[c * r * r + b * r + a] = v[c];
                    }
                    lum[b * r + a] = luminance(v.map(|x| x as f64)) as f32;
                }
            }
            let peak = lum.iter().cloned().fold(0.0f32, f32::max);
            let floor = if peak > 0.0 { 1e-3 * peak } else { 1.0 };
            lum.iter_mut().for_each(|v| *v = v.max(floor));
            (rgb, lum)
        })
        .collect();
    if slices
        .iter()
        .any(|(rgb, _)| rgb.iter().any(|v| !v.is_finite()))
    {
        return Err(RglError::Layout(format!(
            "{} gives non-finite values",
            material.name()
        )));
    }
    let rgb: Vec<f32> = slices.iter().flat_map(|(c, _)| c.iter().copied()).collect();
    let lum: Vec<f32> = slices.iter().flat_map(|(_, l)| l.iter().copied()).collect();

    let description = if opts.description.is_empty() {
        material.name()
    } else {
        opts.description.clone()
    };
    let mut file = TensorFile::default();
    file.push(Field::u8(
        "description",
        &[description.len()],
        description.as_bytes(),
    ));
    file.push(Field::u8("jacobian", &[1], &[opts.jacobian as u8]));
    file.push(Field::f32("theta_i", &[nt], &theta_i));
    file.push(Field::f32("phi_i", &[1], &[0.0]));
    file.push(Field::f32("ndf", &[2, nn], &ndf_grid));
    file.push(Field::f32("sigma", &[2, nn], &sigma_grid));
    file.push(Field::f32("vndf", &[1, nt, rv, rv], &vndf));
    file.push(Field::f32("luminance", &[1, nt, r, r], &lum));
    if opts.spectral {
        let wavelengths = crate::spectrum::spectral_wavelengths();
        let basis = crate::spectrum::rgb_basis(&wavelengths);
        let nl = wavelengths.len();
        let mut spectra = Vec::with_capacity(nt * nl * r * r);
        // per wavelength, the weights of the three channels
        let weights: Vec<[f64; 3]> = (0..nl)
            .map(|k| [basis[0][k], basis[1][k], basis[2][k]])
            .collect();
        for slice in rgb.chunks(3 * r * r) {
            for weights in &weights {
                spectra.extend((0..r * r).map(|p| {
                    (0..3)
                        .map(|c| slice[c * r * r + p] as f64 * weights[c])
                        .sum::<f64>() as f32
                }));
            }
        }
        file.push(Field::f32("wavelengths", &[nl], &wavelengths));
        file.push(Field::f32("spectra", &[1, nt, nl, r, r], &spectra));
    } else {
        file.push(Field::f32("rgb", &[1, nt, 3, r, r], &rgb));
    }
    tracing::debug!(material = %material.name(), bytes = file.to_bytes().len(), "wrote .bsdf tensors");
    Ok(file)
}
