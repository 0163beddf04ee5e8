//! A `.bsdf` file as a material: the fields checked as the renderers check them, evaluated
//! by the same interpolation.

use crate::error::{Result, RglError};
use crate::marginal::Marginal2D;
use crate::tensor::TensorFile;
use brdf::{Brdf, Rgb, Vec3};
use std::f64::consts::{FRAC_PI_2, PI};

/// `θ = u² π/2`: the square-root spacing of elevations in the format.
pub(crate) fn u2theta(u: f64) -> f64 {
    u * u * FRAC_PI_2
}

/// Inverse of [`u2theta`].
pub(crate) fn theta2u(theta: f64) -> f64 {
    (theta / FRAC_PI_2).max(0.0).sqrt()
}

/// `φ = (2u − 1) π`.
pub(crate) fn u2phi(u: f64) -> f64 {
    (2.0 * u - 1.0) * PI
}

/// Inverse of [`u2phi`].
pub(crate) fn phi2u(phi: f64) -> f64 {
    (phi + PI) / (2.0 * PI)
}

/// Elevation of a unit vector, accurate near the pole.
pub(crate) fn elevation(d: &Vec3) -> f64 {
    let dist = (d.x * d.x + d.y * d.y + (d.z - 1.0) * (d.z - 1.0)).sqrt();
    2.0 * (0.5 * dist).clamp(-1.0, 1.0).asin()
}

/// What the reflectance tables of a file hold.
#[derive(Debug, Clone, PartialEq)]
pub enum Channels {
    /// Three RGB channels (the `rgb` field; Mitsuba's RGB variants read it).
    Rgb,
    /// A spectrum sampled at these wavelengths (nm) (the `spectra` and `wavelengths` fields;
    /// spectral renderers read it).
    Spectral(Vec<f32>),
}

/// A material read from an RGL `.bsdf` file (Dupuy & Jakob 2018), evaluated as Mitsuba 3's
/// `measured` BSDF evaluates it: the half vector's coordinates are mapped through the inverse
/// of the visible-normal warp for the incident direction, the reflectance table is
/// interpolated there, and (when the file says so) multiplied by `D(m) / (4 σ(ωi))`.
///
/// The tables hold `f(ωi, ωo) cos θo`; [`Brdf::eval`] divides the cosine out. Spectral files
/// are converted to linear sRGB as seen under D65 light (CIE 1931 observer).
///
/// # Examples
///
/// ```
/// use brdf::{Brdf, Spherical};
/// use rgl_bsdf::{RglBsdf, WriteOptions};
///
/// let lambert = brdf::load("lambert:kd=0.5").unwrap();
/// let file = rgl_bsdf::write(lambert.as_brdf(), &WriteOptions::small()).unwrap();
/// let material = RglBsdf::from_tensor(&file).unwrap();
/// let (wi, wo) = (Spherical::new(0.3, 0.0).to_vector(), Spherical::new(0.8, 2.0).to_vector());
/// let f = material.eval(&wi, &wo);
/// assert!((f[1] - 0.5 / std::f64::consts::PI).abs() < 0.01 * 0.5 / std::f64::consts::PI);
/// ```
#[derive(Debug, Clone)]
pub struct RglBsdf {
    description: String,
    channels: Channels,
    isotropic: bool,
    reduction: i32,
    jacobian: bool,
    ndf: Marginal2D,
    sigma: Marginal2D,
    vndf: Marginal2D,
    spectra: Marginal2D,
    /// `cos θo` at each node of the warped grid, weighted as the reflectance table is (divided
    /// by `D / 4σ` with the jacobian flag), one slice per incident direction.
    cos_o: Marginal2D,
    /// Per stored channel (RGB, or each wavelength), its weights on linear R, G, B.
    to_rgb: Vec<[f64; 3]>,
    resolution: [usize; 4],
}

fn layout(reason: impl Into<String>) -> RglError {
    RglError::Layout(reason.into())
}

impl RglBsdf {
    /// Reads a `.bsdf` file.
    pub fn read(path: impl AsRef<std::path::Path>) -> Result<RglBsdf> {
        RglBsdf::from_tensor(&TensorFile::read(path)?)
    }

    /// The material of a parsed tensor file; every shape relation the renderers rely on is
    /// checked, and every value must be finite (densities non-negative).
    pub fn from_tensor(file: &TensorFile) -> Result<RglBsdf> {
        let description =
            String::from_utf8_lossy(file.require("description")?.to_u8()?).into_owned();
        let jacobian = file.require("jacobian")?;
        if jacobian.shape != [1] {
            return Err(layout("jacobian must hold one byte"));
        }
        let jacobian = jacobian.to_u8()?[0] != 0;
        let vector = |name: &str| -> Result<Vec<f32>> {
            let f = file.require(name)?;
            if f.shape.len() != 1 || f.shape[0] == 0 {
                return Err(layout(format!("{name} must be a non-empty vector")));
            }
            f.to_f32()
        };
        let theta_i = vector("theta_i")?;
        let phi_i = vector("phi_i")?;
        for (name, v) in [("theta_i", &theta_i), ("phi_i", &phi_i)] {
            if v.windows(2).any(|p| p[1] <= p[0]) {
                return Err(layout(format!("{name} must increase")));
            }
        }
        let channels = if file.field("wavelengths").is_some() {
            Channels::Spectral(vector("wavelengths")?)
        } else {
            Channels::Rgb
        };
        let spectra_field = match channels {
            Channels::Rgb => file.require("rgb")?,
            Channels::Spectral(_) => file.require("spectra")?,
        };
        let n_channels = match &channels {
            Channels::Rgb => 3,
            Channels::Spectral(w) => w.len(),
        };
        let (np, nt) = (phi_i.len(), theta_i.len());
        let grid = |name: &str, rank: usize| -> Result<(Vec<usize>, Vec<f32>)> {
            let f = file.require(name)?;
            if f.shape.len() != rank {
                return Err(layout(format!(
                    "{name} must have rank {rank}, not {}",
                    f.shape.len()
                )));
            }
            let (h, w) = (f.shape[rank - 2], f.shape[rank - 1]);
            if h < 2 || w < 2 {
                return Err(layout(format!("{name} needs at least 2 × 2 nodes")));
            }
            Ok((f.shape.clone(), f.to_f32()?))
        };
        let (ndf_shape, ndf) = grid("ndf", 2)?;
        let (sigma_shape, sigma) = grid("sigma", 2)?;
        let (vndf_shape, vndf) = grid("vndf", 4)?;
        let (lum_shape, _) = grid("luminance", 4)?;
        let spectra_shape = spectra_field.shape.clone();
        if spectra_shape.len() != 5 {
            return Err(layout("the reflectance table must have rank 5"));
        }
        let spectra = spectra_field.to_f32()?;
        if vndf_shape[..2] != [np, nt] || lum_shape[..2] != [np, nt] {
            return Err(layout(
                "vndf and luminance must have one slice per (phi_i, theta_i)",
            ));
        }
        if spectra_shape[..3] != [np, nt, n_channels] {
            return Err(layout(format!(
                "the reflectance table's shape {spectra_shape:?} does not match {np} × {nt} × {n_channels}"
            )));
        }
        if spectra_shape[3] != spectra_shape[4]
            || lum_shape[2..] != spectra_shape[3..]
            || lum_shape[2] != lum_shape[3]
        {
            return Err(layout(
                "luminance and reflectance grids must be the same square size",
            ));
        }
        if ndf.iter().chain(&sigma).chain(&vndf).any(|&v| v < 0.0) {
            return Err(layout("ndf, sigma and vndf must be non-negative"));
        }
        if jacobian && sigma.iter().any(|&v| v <= 0.0) {
            return Err(layout(
                "sigma must be positive when the jacobian flag is set",
            ));
        }
        if vndf
            .chunks(vndf_shape[2] * vndf_shape[3])
            .any(|s| s.iter().all(|&v| v == 0.0))
        {
            return Err(layout("a vndf slice is zero everywhere"));
        }
        let isotropic = np <= 2;
        let reduction = if isotropic {
            0
        } else {
            (2.0 * PI / (phi_i[np - 1] - phi_i[0]) as f64).round() as i32
        };
        let params2 = vec![phi_i.clone(), theta_i.clone()];
        let wavelengths = match &channels {
            Channels::Rgb => vec![0.0, 1.0, 2.0],
            Channels::Spectral(w) => w.clone(),
        };
        if wavelengths.windows(2).any(|p| p[1] <= p[0]) {
            return Err(layout("wavelengths must increase"));
        }
        let to_rgb = match &channels {
            Channels::Rgb => vec![[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]],
            Channels::Spectral(w) => crate::spectrum::rgb_weights(w),
        };
        let ndf = Marginal2D::new(&ndf, ndf_shape[1], ndf_shape[0], vec![], false, false);
        let sigma = Marginal2D::new(&sigma, sigma_shape[1], sigma_shape[0], vec![], false, false);
        let vndf = Marginal2D::new(
            &vndf,
            vndf_shape[3],
            vndf_shape[2],
            params2.clone(),
            true,
            true,
        );
        let r = [spectra_shape[3], spectra_shape[4]];
        let mut cos_o = Vec::with_capacity(np * nt * r[0] * r[1]);
        for &p in &params2[0] {
            for &t in &params2[1] {
                let (p, t) = (p as f64, t as f64);
                let wi = Vec3::new(t.sin() * p.cos(), t.sin() * p.sin(), t.cos());
                let scale_i = 4.0 * sigma.eval([theta2u(t), phi2u(p)], &[]);
                for b in 0..r[0] {
                    for a in 0..r[1] {
                        let s = [a as f64 / (r[1] - 1) as f64, b as f64 / (r[0] - 1) as f64];
                        let (u_m, _) = vndf.sample(s, &[p, t]);
                        let (tm, pm) = (
                            u2theta(u_m[0]),
                            u2phi(u_m[1]) + if isotropic { p } else { 0.0 },
                        );
                        let m = Vec3::new(tm.sin() * pm.cos(), tm.sin() * pm.sin(), tm.cos());
                        let cos = (2.0 * m.dot(&wi) * m.z - wi.z).max(0.0);
                        let weight = if jacobian {
                            let d = ndf.eval(u_m, &[]);
                            if d > 0.0 {
                                scale_i / d
                            } else {
                                0.0
                            }
                        } else {
                            1.0
                        };
                        cos_o.push((cos * weight) as f32);
                    }
                }
            }
        }
        let cos_o = Marginal2D::new(&cos_o, r[1], r[0], params2, false, false);
        Ok(RglBsdf {
            description,
            cos_o,
            isotropic,
            reduction,
            jacobian,
            ndf,
            sigma,
            vndf,
            spectra: Marginal2D::new(
                &spectra,
                spectra_shape[4],
                spectra_shape[3],
                vec![phi_i, theta_i, wavelengths],
                false,
                false,
            ),
            to_rgb,
            resolution: [np, nt, spectra_shape[3], spectra_shape[4]],
            channels,
        })
    }

    /// The file's description string.
    pub fn description(&self) -> &str {
        &self.description
    }

    /// What the reflectance tables hold.
    pub fn channels(&self) -> &Channels {
        &self.channels
    }

    /// Grid sizes: incident azimuths, incident elevations, then the reflectance grid's rows
    /// and columns.
    pub fn resolution(&self) -> [usize; 4] {
        self.resolution
    }

    /// Whether the file is isotropic (at most two incident azimuths).
    pub fn isotropic(&self) -> bool {
        self.isotropic
    }

    /// The stored channels at (`wi`, `wo`), `f cos θo`, one value per channel of the file
    /// (zero below the horizon).
    pub fn eval_channels(&self, wi: &Vec3, wo: &Vec3) -> Vec<f64> {
        match self.locate(wi, wo) {
            None => vec![0.0; self.to_rgb.len()],
            Some(at) => self.channels_at(&at, true),
        }
    }

    /// Where (`wi`, `wo`) falls in the file: the point of the warped grid, the incident
    /// direction's parameters and the `D / 4σ` factor; `None` below the horizon.
    fn locate(&self, wi: &Vec3, wo: &Vec3) -> Option<Located> {
        if wi.z <= 0.0 || wo.z <= 0.0 {
            return None;
        }
        let (mut wi, mut wo) = (*wi, *wo);
        if self.reduction >= 2 {
            // fold into the stored part of the azimuth range, as the renderers do
            let sy = wi.y;
            let sx = if self.reduction == 4 { wi.x } else { sy };
            let flip = |v: f64, s: f64| if s >= 0.0 { -v } else { v };
            wi.x = flip(wi.x, sx);
            wi.y = flip(wi.y, sy);
            wo.x = flip(wo.x, sx);
            wo.y = flip(wo.y, sy);
        }
        let m = (wi + wo).normalize();
        let (theta_i, phi_i) = (elevation(&wi), wi.y.atan2(wi.x));
        let (theta_m, phi_m) = (elevation(&m), m.y.atan2(m.x));
        let u_wi = [theta2u(theta_i), phi2u(phi_i)];
        let mut u_m = [
            theta2u(theta_m),
            phi2u(if self.isotropic { phi_m - phi_i } else { phi_m }),
        ];
        u_m[1] -= u_m[1].floor();
        let (sample, _) = self.vndf.invert(u_m, &[phi_i, theta_i]);
        let scale = if self.jacobian {
            self.ndf.eval(u_m, &[]) / (4.0 * self.sigma.eval(u_wi, &[]))
        } else {
            1.0
        };
        Some(Located {
            sample,
            phi_i,
            theta_i,
            scale,
        })
    }

    /// The stored channels at a located point, times the `D / 4σ` factor if `scaled`.
    fn channels_at(&self, at: &Located, scaled: bool) -> Vec<f64> {
        let scale = if scaled { at.scale } else { 1.0 };
        let wavelengths = match &self.channels {
            Channels::Rgb => vec![0.0, 1.0, 2.0],
            Channels::Spectral(w) => w.iter().map(|&v| v as f64).collect(),
        };
        wavelengths
            .iter()
            .map(|&l| self.spectra.eval(at.sample, &[at.phi_i, at.theta_i, l]) * scale)
            .collect()
    }

    fn to_rgb(&self, c: &[f64]) -> Rgb {
        let mut rgb = [0.0; 3];
        for (v, w) in c.iter().zip(&self.to_rgb) {
            for k in 0..3 {
                rgb[k] += v * w[k];
            }
        }
        rgb
    }

    /// Linear sRGB `f cos θo` at (`wi`, `wo`), as a renderer evaluates the file.
    pub fn eval_cos(&self, wi: &Vec3, wo: &Vec3) -> Rgb {
        self.to_rgb(&self.eval_channels(wi, wo))
    }
}

/// A direction pair located in a file's grids.
struct Located {
    sample: [f64; 2],
    phi_i: f64,
    theta_i: f64,
    scale: f64,
}

impl Brdf for RglBsdf {
    /// The BRDF value: the reflectance table interpolated at (`wi`, `wo`) divided by `cos θo`
    /// interpolated from the same nodes, i.e. a weighted mean of the BRDF values at the
    /// surrounding nodes. (Dividing [`RglBsdf::eval_cos`] by the exact `cos θo` instead would
    /// amplify the interpolation error near grazing angles without bound.)
    fn eval(&self, wi: &Vec3, wo: &Vec3) -> Rgb {
        let Some(at) = self.locate(wi, wo) else {
            return [0.0; 3];
        };
        let cos = self.cos_o.eval(at.sample, &[at.phi_i, at.theta_i]);
        if cos <= 0.0 {
            return [0.0; 3];
        }
        self.to_rgb(&self.channels_at(&at, false)).map(|v| v / cos)
    }

    fn name(&self) -> String {
        if self.description.is_empty() {
            "rgl".into()
        } else {
            self.description.clone()
        }
    }

    fn is_isotropic(&self) -> bool {
        self.isotropic
    }
}

/// The material-spec form `rgl:<file.bsdf>`, and any path ending in `.bsdf`.
///
/// # Examples
///
/// ```
/// use std::sync::Arc;
/// let dir = tempfile::tempdir().unwrap();
/// let path = dir.path().join("grey.bsdf");
/// let lambert = brdf::load("lambert:kd=0.4").unwrap();
/// rgl_bsdf::write(lambert.as_brdf(), &rgl_bsdf::WriteOptions::small()).unwrap().write(&path).unwrap();
/// brdf::register(Arc::new(rgl_bsdf::RglSpecs)).unwrap();
/// let m = brdf::load(path.to_str().unwrap()).unwrap();
/// assert_eq!(m.as_brdf().name(), "lambert");
/// ```
#[derive(Debug, Clone, Copy, Default)]
pub struct RglSpecs;

impl brdf::SpecResolver for RglSpecs {
    fn prefix(&self) -> &str {
        "rgl"
    }

    fn form(&self) -> &str {
        "rgl:<file.bsdf>"
    }

    fn extensions(&self) -> &[&str] {
        &["bsdf"]
    }

    fn load(&self, spec: &str, rest: &str) -> brdf::Result<brdf::Material> {
        if rest.is_empty() {
            return Err(brdf::spec_error(spec, "expected rgl:<file.bsdf>"));
        }
        let m = RglBsdf::read(rest).map_err(|e| brdf::resolver_error(spec, e))?;
        Ok(brdf::Material::Resolved(Box::new(m)))
    }
}
