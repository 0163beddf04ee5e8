//! Analytic reflectance models, all behind the [`Brdf`] trait.
//!
//! Every model returns zero below the horizon and is reciprocal. Colour parameters are RGB.
//! Models that promise energy conservation (directional albedo ≤ 1) say so, with the condition.

use crate::coords::{polar_angle, Vec3};
use crate::error::{BrdfError, Result};
use crate::{Brdf, Rgb};
use std::f64::consts::{FRAC_1_PI, PI};

pub mod htsg;
pub use htsg::Htsg;

fn below(wi: &Vec3, wo: &Vec3) -> bool {
    wi.z <= 0.0 || wo.z <= 0.0
}

fn half_vector(wi: &Vec3, wo: &Vec3) -> Vec3 {
    let s = wi + wo;
    let n = s.norm();
    if n > 0.0 {
        s / n
    } else {
        Vec3::z()
    }
}

fn add_scaled(a: Rgb, b: Rgb, s: f64) -> Rgb {
    [a[0] + b[0] * s, a[1] + b[1] * s, a[2] + b[2] * s]
}

fn scale(a: Rgb, s: f64) -> Rgb {
    [a[0] * s, a[1] * s, a[2] * s]
}

/// Checks that a parameter is finite and within `[lo, hi]`.
pub(crate) fn check_param(model: &str, param: &str, value: f64, lo: f64, hi: f64) -> Result<()> {
    if value.is_finite() && value >= lo && value <= hi {
        Ok(())
    } else {
        Err(BrdfError::Parameter {
            model: model.into(),
            param: param.into(),
            value,
            reason: format!("must be finite and within [{lo}, {hi}]"),
        })
    }
}

fn check_rgb(model: &str, param: &str, v: &Rgb, lo: f64, hi: f64) -> Result<()> {
    v.iter()
        .try_for_each(|c| check_param(model, param, *c, lo, hi))
}

/// Unpolarised Fresnel reflectance of a dielectric with relative index `eta` at incidence cosine
/// `cos_i` (exact formula).
pub fn fresnel_dielectric(cos_i: f64, eta: f64) -> f64 {
    let c = cos_i.abs().min(1.0);
    let g2 = eta * eta - 1.0 + c * c;
    if g2 <= 0.0 {
        return 1.0;
    }
    let g = g2.sqrt();
    let a = (g - c) / (g + c);
    let b = (c * (g + c) - 1.0) / (c * (g - c) + 1.0);
    0.5 * a * a * (1.0 + b * b)
}

/// Schlick's approximation of Fresnel reflectance with normal-incidence reflectance `f0`.
pub fn fresnel_schlick(cos_i: f64, f0: f64) -> f64 {
    f0 + (1.0 - f0) * (1.0 - cos_i.clamp(0.0, 1.0)).powi(5)
}

/// An isotropic microfacet normal distribution, normalised so that ∫ D(h) cos θh dω = 1.
pub trait MicrofacetDistribution {
    /// Density of microfacet normals at polar angle with cosine `cos_h`.
    fn d(&self, cos_h: f64) -> f64;
}

/// Beckmann distribution with RMS slope `m`.
#[derive(Debug, Clone, Copy)]
pub struct Beckmann {
    /// RMS slope of the microfacets.
    pub m: f64,
}

impl MicrofacetDistribution for Beckmann {
    fn d(&self, cos_h: f64) -> f64 {
        if cos_h <= 0.0 {
            return 0.0;
        }
        let c2 = cos_h * cos_h;
        let tan2 = (1.0 - c2) / c2;
        let m2 = self.m * self.m;
        (-tan2 / m2).exp() / (PI * m2 * c2 * c2)
    }
}

/// GGX / Trowbridge-Reitz distribution with roughness `alpha`.
#[derive(Debug, Clone, Copy)]
pub struct TrowbridgeReitz {
    /// Width parameter α.
    pub alpha: f64,
}

impl MicrofacetDistribution for TrowbridgeReitz {
    fn d(&self, cos_h: f64) -> f64 {
        if cos_h <= 0.0 {
            return 0.0;
        }
        let c2 = cos_h * cos_h;
        let a2 = self.alpha * self.alpha;
        let t = c2 * (a2 - 1.0) + 1.0;
        a2 / (PI * t * t)
    }
}

impl TrowbridgeReitz {
    /// Smith's Λ for a direction with cosine `cos_t` to the normal.
    pub fn lambda(&self, cos_t: f64) -> f64 {
        let c2 = (cos_t * cos_t).max(1e-300);
        let tan2 = ((1.0 - c2) / c2).max(0.0);
        0.5 * (-1.0 + (1.0 + self.alpha * self.alpha * tan2).sqrt())
    }
}

/// Normalised Blinn-Phong distribution, (n + 2)/(2π) cosⁿ θh.
#[derive(Debug, Clone, Copy)]
pub struct BlinnDistribution {
    /// Phong exponent n.
    pub exponent: f64,
}

impl MicrofacetDistribution for BlinnDistribution {
    fn d(&self, cos_h: f64) -> f64 {
        if cos_h <= 0.0 {
            return 0.0;
        }
        (self.exponent + 2.0) / (2.0 * PI) * cos_h.powf(self.exponent)
    }
}

/// Ideal diffuse reflection, f = kd/π. Albedo = kd.
#[derive(Debug, Clone, PartialEq)]
pub struct Lambert {
    /// Diffuse albedo per channel, in `[0, 1]` for a physical surface.
    pub kd: Rgb,
}

impl Lambert {
    /// Checks the parameters.
    pub fn validate(&self) -> Result<()> {
        check_rgb("lambert", "kd", &self.kd, 0.0, 1.0)
    }
}

impl Brdf for Lambert {
    fn eval(&self, wi: &Vec3, wo: &Vec3) -> Rgb {
        if below(wi, wo) {
            return [0.0; 3];
        }
        scale(self.kd, FRAC_1_PI)
    }
    fn name(&self) -> String {
        "lambert".into()
    }
}

/// The modified Phong model (Lafortune & Willems 1994): kd/π + ks (n+2)/(2π) cosⁿ α, with α
/// the angle between ωo and the mirror direction of ωi. Reciprocal, and energy conserving when
/// kd + ks ≤ 1 per channel.
#[derive(Debug, Clone, PartialEq)]
pub struct Phong {
    /// Diffuse albedo.
    pub kd: Rgb,
    /// Specular albedo at normal incidence.
    pub ks: Rgb,
    /// Specular exponent n ≥ 0.
    pub exponent: f64,
}

impl Phong {
    /// Checks the parameters.
    pub fn validate(&self) -> Result<()> {
        check_rgb("phong", "kd", &self.kd, 0.0, 1.0)?;
        check_rgb("phong", "ks", &self.ks, 0.0, 1.0)?;
        check_param("phong", "n", self.exponent, 0.0, 1e7)
    }
}

impl Brdf for Phong {
    fn eval(&self, wi: &Vec3, wo: &Vec3) -> Rgb {
        if below(wi, wo) {
            return [0.0; 3];
        }
        let r = crate::coords::reflect_z(wi);
        let c = r.dot(wo).max(0.0);
        let s = (self.exponent + 2.0) / (2.0 * PI) * c.powf(self.exponent);
        add_scaled(scale(self.kd, FRAC_1_PI), self.ks, s)
    }
    fn name(&self) -> String {
        "phong".into()
    }
}

/// Blinn-Phong: kd/π + ks (n+8)/(8π) cosⁿ θh (the usual approximate normalisation).
#[derive(Debug, Clone, PartialEq)]
pub struct BlinnPhong {
    /// Diffuse albedo.
    pub kd: Rgb,
    /// Specular coefficient.
    pub ks: Rgb,
    /// Exponent n ≥ 0.
    pub exponent: f64,
}

impl BlinnPhong {
    /// Checks the parameters.
    pub fn validate(&self) -> Result<()> {
        check_rgb("blinn", "kd", &self.kd, 0.0, 1.0)?;
        check_rgb("blinn", "ks", &self.ks, 0.0, 1.0)?;
        check_param("blinn", "n", self.exponent, 0.0, 1e7)
    }
}

impl Brdf for BlinnPhong {
    fn eval(&self, wi: &Vec3, wo: &Vec3) -> Rgb {
        if below(wi, wo) {
            return [0.0; 3];
        }
        let h = half_vector(wi, wo);
        let s = (self.exponent + 8.0) / (8.0 * PI) * h.z.max(0.0).powf(self.exponent);
        add_scaled(scale(self.kd, FRAC_1_PI), self.ks, s)
    }
    fn name(&self) -> String {
        "blinn".into()
    }
}

/// One lobe of the Lafortune model: ρ · max(0, Cx ux vx + Cy uy vy + Cz uz vz)ⁿ.
#[derive(Debug, Clone, PartialEq)]
pub struct LafortuneLobe {
    /// Cx (negative for a forward-scattering lobe).
    pub cx: f64,
    /// Cy (equal to Cx for an isotropic lobe).
    pub cy: f64,
    /// Cz.
    pub cz: f64,
    /// Exponent n.
    pub exponent: f64,
    /// Lobe albedo factor per channel.
    pub rho: Rgb,
}

/// The multi-lobe Lafortune model: kd/π + Σ lobes.
#[derive(Debug, Clone, PartialEq)]
pub struct Lafortune {
    /// Diffuse albedo.
    pub kd: Rgb,
    /// Generalised cosine lobes.
    pub lobes: Vec<LafortuneLobe>,
}

impl Lafortune {
    /// Checks the parameters.
    pub fn validate(&self) -> Result<()> {
        check_rgb("lafortune", "kd", &self.kd, 0.0, 1.0)?;
        for l in &self.lobes {
            for (p, v) in [("cx", l.cx), ("cy", l.cy), ("cz", l.cz)] {
                check_param("lafortune", p, v, -1e6, 1e6)?;
            }
            check_param("lafortune", "n", l.exponent, 0.0, 1e7)?;
            check_rgb("lafortune", "rho", &l.rho, 0.0, 1e6)?;
        }
        Ok(())
    }
}

impl Brdf for Lafortune {
    fn eval(&self, wi: &Vec3, wo: &Vec3) -> Rgb {
        if below(wi, wo) {
            return [0.0; 3];
        }
        let mut out = scale(self.kd, FRAC_1_PI);
        for l in &self.lobes {
            let base = l.cx * wi.x * wo.x + l.cy * wi.y * wo.y + l.cz * wi.z * wo.z;
            if base > 0.0 {
                out = add_scaled(out, l.rho, base.powf(l.exponent));
            }
        }
        out
    }
    fn name(&self) -> String {
        "lafortune".into()
    }
    fn is_isotropic(&self) -> bool {
        self.lobes.iter().all(|l| l.cx == l.cy)
    }
}

/// Ward's model: kd/π + ks exp(−tan²θh (cos²φh/αx² + sin²φh/αy²)) / (4π αx αy √(cos θi cos θo)).
/// Isotropic when αx = αy. Not energy conserving at grazing angles.
#[derive(Debug, Clone, PartialEq)]
pub struct Ward {
    /// Diffuse albedo.
    pub kd: Rgb,
    /// Specular albedo.
    pub ks: Rgb,
    /// Roughness along the tangent x.
    pub alpha_x: f64,
    /// Roughness along the tangent y.
    pub alpha_y: f64,
}

impl Ward {
    /// Checks the parameters.
    pub fn validate(&self) -> Result<()> {
        check_rgb("ward", "kd", &self.kd, 0.0, 1.0)?;
        check_rgb("ward", "ks", &self.ks, 0.0, 1.0)?;
        check_param("ward", "alpha_x", self.alpha_x, 1e-4, 10.0)?;
        check_param("ward", "alpha_y", self.alpha_y, 1e-4, 10.0)
    }
}

impl Brdf for Ward {
    fn eval(&self, wi: &Vec3, wo: &Vec3) -> Rgb {
        if below(wi, wo) {
            return [0.0; 3];
        }
        let h = half_vector(wi, wo);
        let hz2 = (h.z * h.z).max(1e-300);
        let e = (h.x * h.x / (self.alpha_x * self.alpha_x)
            + h.y * h.y / (self.alpha_y * self.alpha_y))
            / hz2;
        let s = (-e).exp() / (4.0 * PI * self.alpha_x * self.alpha_y * (wi.z * wo.z).sqrt());
        add_scaled(scale(self.kd, FRAC_1_PI), self.ks, s)
    }
    fn name(&self) -> String {
        "ward".into()
    }
    fn is_isotropic(&self) -> bool {
        self.alpha_x == self.alpha_y
    }
}

/// Cook-Torrance: kd/π + ks D F G / (4 cos θi cos θo) with the Beckmann distribution, the exact
/// dielectric Fresnel term and the V-cavity shadowing-masking term. With kd + ks ≤ 1 the albedo
/// stays ≤ 1.
#[derive(Debug, Clone, PartialEq)]
pub struct CookTorrance {
    /// Diffuse albedo.
    pub kd: Rgb,
    /// Specular scale.
    pub ks: Rgb,
    /// Beckmann RMS slope.
    pub m: f64,
    /// Relative index of refraction for the Fresnel term.
    pub ior: f64,
}

impl CookTorrance {
    /// Checks the parameters.
    pub fn validate(&self) -> Result<()> {
        check_rgb("cook-torrance", "kd", &self.kd, 0.0, 1.0)?;
        check_rgb("cook-torrance", "ks", &self.ks, 0.0, 1.0)?;
        check_param("cook-torrance", "m", self.m, 1e-4, 10.0)?;
        check_param("cook-torrance", "ior", self.ior, 1.0, 100.0)
    }
}

impl Brdf for CookTorrance {
    fn eval(&self, wi: &Vec3, wo: &Vec3) -> Rgb {
        if below(wi, wo) {
            return [0.0; 3];
        }
        let h = half_vector(wi, wo);
        let oh = wo.dot(&h).max(1e-12);
        let d = Beckmann { m: self.m }.d(h.z);
        let g = (2.0 * h.z * wo.z / oh).min(2.0 * h.z * wi.z / oh).min(1.0);
        let f = fresnel_dielectric(wi.dot(&h), self.ior);
        let s = d * f * g / (4.0 * wi.z * wo.z);
        add_scaled(scale(self.kd, FRAC_1_PI), self.ks, s)
    }
    fn name(&self) -> String {
        "cook-torrance".into()
    }
}

/// GGX (Trowbridge-Reitz) microfacet model with Smith height-correlated masking-shadowing and the
/// exact dielectric Fresnel term: kd/π + ks D F G₂ / (4 cos θi cos θo). With kd + ks ≤ 1 the
/// albedo stays ≤ 1.
#[derive(Debug, Clone, PartialEq)]
pub struct Ggx {
    /// Diffuse albedo.
    pub kd: Rgb,
    /// Specular scale.
    pub ks: Rgb,
    /// Roughness α.
    pub alpha: f64,
    /// Relative index of refraction.
    pub ior: f64,
}

impl Ggx {
    /// Checks the parameters.
    pub fn validate(&self) -> Result<()> {
        check_rgb("ggx", "kd", &self.kd, 0.0, 1.0)?;
        check_rgb("ggx", "ks", &self.ks, 0.0, 1.0)?;
        check_param("ggx", "alpha", self.alpha, 1e-4, 10.0)?;
        check_param("ggx", "ior", self.ior, 1.0, 100.0)
    }
}

impl Brdf for Ggx {
    fn eval(&self, wi: &Vec3, wo: &Vec3) -> Rgb {
        if below(wi, wo) {
            return [0.0; 3];
        }
        let dist = TrowbridgeReitz { alpha: self.alpha };
        let h = half_vector(wi, wo);
        let g = 1.0 / (1.0 + dist.lambda(wi.z) + dist.lambda(wo.z));
        let f = fresnel_dielectric(wi.dot(&h), self.ior);
        let s = dist.d(h.z) * f * g / (4.0 * wi.z * wo.z);
        add_scaled(scale(self.kd, FRAC_1_PI), self.ks, s)
    }
    fn name(&self) -> String {
        "ggx".into()
    }
}

/// The Oren-Nayar model (qualitative form) of a rough diffuse surface with facet slope deviation
/// σ (radians).
#[derive(Debug, Clone, PartialEq)]
pub struct OrenNayar {
    /// Albedo of the facets.
    pub albedo: Rgb,
    /// Standard deviation of facet slope angles, radians.
    pub sigma: f64,
}

impl OrenNayar {
    /// Checks the parameters.
    pub fn validate(&self) -> Result<()> {
        check_rgb("oren-nayar", "albedo", &self.albedo, 0.0, 1.0)?;
        check_param("oren-nayar", "sigma", self.sigma, 0.0, PI / 2.0)
    }
}

impl Brdf for OrenNayar {
    fn eval(&self, wi: &Vec3, wo: &Vec3) -> Rgb {
        if below(wi, wo) {
            return [0.0; 3];
        }
        let s2 = self.sigma * self.sigma;
        let a = 1.0 - 0.5 * s2 / (s2 + 0.33);
        let b = 0.45 * s2 / (s2 + 0.09);
        let (ti, to) = (polar_angle(wi), polar_angle(wo));
        let (alpha, beta) = (ti.max(to), ti.min(to));
        let pi_ = (wi.x * wi.x + wi.y * wi.y).sqrt();
        let po = (wo.x * wo.x + wo.y * wo.y).sqrt();
        let cos_dphi = if pi_ > 1e-12 && po > 1e-12 {
            ((wi.x * wo.x + wi.y * wo.y) / (pi_ * po)).max(0.0)
        } else {
            0.0
        };
        let k = a + b * cos_dphi * alpha.sin() * beta.tan();
        scale(self.albedo, k * FRAC_1_PI)
    }
    fn name(&self) -> String {
        "oren-nayar".into()
    }
}

/// The Ashikhmin-Shirley model: a coupled diffuse term and an anisotropic Phong-like specular
/// lobe with Schlick Fresnel, designed to conserve energy.
#[derive(Debug, Clone, PartialEq)]
pub struct AshikhminShirley {
    /// Diffuse reflectance Rd.
    pub rd: Rgb,
    /// Specular reflectance at normal incidence Rs.
    pub rs: Rgb,
    /// Exponent along the tangent x.
    pub nu: f64,
    /// Exponent along the tangent y.
    pub nv: f64,
}

impl AshikhminShirley {
    /// Checks the parameters.
    pub fn validate(&self) -> Result<()> {
        check_rgb("ashikhmin-shirley", "rd", &self.rd, 0.0, 1.0)?;
        check_rgb("ashikhmin-shirley", "rs", &self.rs, 0.0, 1.0)?;
        check_param("ashikhmin-shirley", "nu", self.nu, 0.0, 1e7)?;
        check_param("ashikhmin-shirley", "nv", self.nv, 0.0, 1e7)
    }
}

impl Brdf for AshikhminShirley {
    fn eval(&self, wi: &Vec3, wo: &Vec3) -> Rgb {
        if below(wi, wo) {
            return [0.0; 3];
        }
        let h = half_vector(wi, wo);
        let kh = wi.dot(&h).max(1e-12);
        let sin2 = 1.0 - h.z * h.z;
        let lobe = if sin2 > 1e-14 {
            let e = (self.nu * h.x * h.x + self.nv * h.y * h.y) / sin2;
            h.z.max(0.0).powf(e)
        } else {
            1.0
        };
        let spec_norm = ((self.nu + 1.0) * (self.nv + 1.0)).sqrt() / (8.0 * PI);
        let spec = spec_norm * lobe / (kh * wi.z.max(wo.z));
        let di = 1.0 - (1.0 - wi.z / 2.0).powi(5);
        let dout = 1.0 - (1.0 - wo.z / 2.0).powi(5);
        let mut out = [0.0; 3];
        for c in 0..3 {
            let diffuse = 28.0 * self.rd[c] / (23.0 * PI) * (1.0 - self.rs[c]) * di * dout;
            out[c] = diffuse + spec * fresnel_schlick(kh, self.rs[c]);
        }
        out
    }
    fn name(&self) -> String {
        "ashikhmin-shirley".into()
    }
    fn is_isotropic(&self) -> bool {
        self.nu == self.nv
    }
}

/// Two-lobe GGX: kd/π + Σₖ ksₖ Dₖ F G₂ₖ / (4 cos θi cos θo), two [`Ggx`] specular lobes of
/// different roughness sharing one Fresnel index (a sharp coat over a broader base, or the
/// two-scale roughness of many metals). With kd + ks₁ + ks₂ ≤ 1 the albedo stays ≤ 1.
#[derive(Debug, Clone, PartialEq)]
pub struct GgxTwoLobe {
    /// Diffuse albedo.
    pub kd: Rgb,
    /// Specular scale of each lobe.
    pub ks: [Rgb; 2],
    /// Roughness α of each lobe.
    pub alpha: [f64; 2],
    /// Relative index of refraction shared by both lobes.
    pub ior: f64,
}

impl GgxTwoLobe {
    /// Checks the parameters.
    pub fn validate(&self) -> Result<()> {
        check_rgb("ggx2", "kd", &self.kd, 0.0, 1.0)?;
        for k in 0..2 {
            check_rgb("ggx2", "ks", &self.ks[k], 0.0, 1.0)?;
            check_param("ggx2", "alpha", self.alpha[k], 1e-4, 10.0)?;
        }
        check_param("ggx2", "ior", self.ior, 1.0, 100.0)
    }
}

impl Brdf for GgxTwoLobe {
    fn eval(&self, wi: &Vec3, wo: &Vec3) -> Rgb {
        if below(wi, wo) {
            return [0.0; 3];
        }
        let mut out = scale(self.kd, FRAC_1_PI);
        for k in 0..2 {
            let lobe = Ggx {
                kd: [0.0; 3],
                ks: self.ks[k],
                alpha: self.alpha[k],
                ior: self.ior,
            };
            let v = lobe.eval(wi, wo);
            out = add_scaled(out, v, 1.0);
        }
        out
    }
    fn name(&self) -> String {
        "ggx2".into()
    }
}

/// Two-lobe Cook-Torrance: kd/π + Σₖ ksₖ Dₖ F G / (4 cos θi cos θo), two Beckmann lobes of
/// different RMS slope sharing one Fresnel index. With kd + ks₁ + ks₂ ≤ 1 the albedo stays ≤ 1.
#[derive(Debug, Clone, PartialEq)]
pub struct CookTorranceTwoLobe {
    /// Diffuse albedo.
    pub kd: Rgb,
    /// Specular scale of each lobe.
    pub ks: [Rgb; 2],
    /// Beckmann RMS slope of each lobe.
    pub m: [f64; 2],
    /// Relative index of refraction shared by both lobes.
    pub ior: f64,
}

impl CookTorranceTwoLobe {
    /// Checks the parameters.
    pub fn validate(&self) -> Result<()> {
        check_rgb("ct2", "kd", &self.kd, 0.0, 1.0)?;
        for k in 0..2 {
            check_rgb("ct2", "ks", &self.ks[k], 0.0, 1.0)?;
            check_param("ct2", "m", self.m[k], 1e-4, 10.0)?;
        }
        check_param("ct2", "ior", self.ior, 1.0, 100.0)
    }
}

impl Brdf for CookTorranceTwoLobe {
    fn eval(&self, wi: &Vec3, wo: &Vec3) -> Rgb {
        if below(wi, wo) {
            return [0.0; 3];
        }
        let mut out = scale(self.kd, FRAC_1_PI);
        for k in 0..2 {
            let lobe = CookTorrance {
                kd: [0.0; 3],
                ks: self.ks[k],
                m: self.m[k],
                ior: self.ior,
            };
            out = add_scaled(out, lobe.eval(wi, wo), 1.0);
        }
        out
    }
    fn name(&self) -> String {
        "ct2".into()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::coords::Spherical;
    use crate::summary::directional_albedo;
    use rand::{Rng, SeedableRng};

    pub(crate) fn all_models() -> Vec<Box<dyn Brdf>> {
        vec![
            Box::new(Lambert {
                kd: [0.8, 0.5, 0.2],
            }),
            Box::new(Phong {
                kd: [0.3, 0.2, 0.1],
                ks: [0.6, 0.7, 0.8],
                exponent: 40.0,
            }),
            Box::new(BlinnPhong {
                kd: [0.3; 3],
                ks: [0.5; 3],
                exponent: 60.0,
            }),
            Box::new(Lafortune {
                kd: [0.2; 3],
                lobes: vec![
                    LafortuneLobe {
                        cx: -1.0,
                        cy: -1.0,
                        cz: 0.95,
                        exponent: 20.0,
                        rho: [0.5, 0.4, 0.3],
                    },
                    LafortuneLobe {
                        cx: 0.3,
                        cy: 0.3,
                        cz: 0.3,
                        exponent: 2.0,
                        rho: [0.1; 3],
                    },
                ],
            }),
            Box::new(Ward {
                kd: [0.2; 3],
                ks: [0.3; 3],
                alpha_x: 0.15,
                alpha_y: 0.15,
            }),
            Box::new(Ward {
                kd: [0.2; 3],
                ks: [0.3; 3],
                alpha_x: 0.1,
                alpha_y: 0.4,
            }),
            Box::new(CookTorrance {
                kd: [0.2; 3],
                ks: [0.8; 3],
                m: 0.2,
                ior: 1.5,
            }),
            Box::new(Ggx {
                kd: [0.1, 0.2, 0.3],
                ks: [0.7; 3],
                alpha: 0.15,
                ior: 1.6,
            }),
            Box::new(OrenNayar {
                albedo: [0.9, 0.6, 0.3],
                sigma: 0.5,
            }),
            Box::new(AshikhminShirley {
                rd: [0.5, 0.4, 0.3],
                rs: [0.05; 3],
                nu: 100.0,
                nv: 100.0,
            }),
            Box::new(AshikhminShirley {
                rd: [0.5; 3],
                rs: [0.05; 3],
                nu: 10.0,
                nv: 500.0,
            }),
            Box::new(GgxTwoLobe {
                kd: [0.1; 3],
                ks: [[0.3; 3], [0.2, 0.3, 0.4]],
                alpha: [0.05, 0.4],
                ior: 1.8,
            }),
            Box::new(CookTorranceTwoLobe {
                kd: [0.1; 3],
                ks: [[0.3; 3], [0.2, 0.3, 0.4]],
                m: [0.05, 0.4],
                ior: 1.8,
            }),
            Box::new(Htsg {
                kd: [0.1, 0.2, 0.3],
                ks: [1.0, 0.8, 0.6],
                sigma: 0.2,
                tau: 2.0,
                ior: 1.5,
            }),
        ]
    }

    fn random_dir(rng: &mut impl Rng) -> Vec3 {
        Spherical::new(
            rng.gen_range(0.0..std::f64::consts::FRAC_PI_2),
            rng.gen_range(0.0..std::f64::consts::TAU),
        )
        .to_vector()
    }

    #[test]
    fn every_model_is_reciprocal_and_non_negative() {
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(11);
        for m in all_models() {
            for _ in 0..5000 {
                let (wi, wo) = (random_dir(&mut rng), random_dir(&mut rng));
                let a = m.eval(&wi, &wo);
                let b = m.eval(&wo, &wi);
                for c in 0..3 {
                    assert!(a[c] >= 0.0 && a[c].is_finite(), "{} {a:?}", m.name());
                    assert!(
                        (a[c] - b[c]).abs() <= 1e-9 * a[c].abs().max(1.0),
                        "{} not reciprocal: {a:?} vs {b:?}",
                        m.name()
                    );
                }
                // Below the horizon there is no reflection.
                let under = Vec3::new(wi.x, wi.y, -wi.z - 1e-3);
                assert_eq!(m.eval(&under, &wo), [0.0; 3]);
            }
        }
    }

    #[test]
    fn energy_conserving_models_keep_albedo_below_one() {
        let conserving: Vec<Box<dyn Brdf>> = vec![
            Box::new(Lambert { kd: [1.0; 3] }),
            Box::new(Phong {
                kd: [0.5; 3],
                ks: [0.5; 3],
                exponent: 10.0,
            }),
            Box::new(Phong {
                kd: [0.0; 3],
                ks: [1.0; 3],
                exponent: 1.0,
            }),
            Box::new(CookTorrance {
                kd: [0.0; 3],
                ks: [1.0; 3],
                m: 0.5,
                ior: 50.0,
            }),
            Box::new(Ggx {
                kd: [0.3; 3],
                ks: [0.7; 3],
                alpha: 0.6,
                ior: 50.0,
            }),
            Box::new(OrenNayar {
                albedo: [1.0; 3],
                sigma: 1.0,
            }),
            Box::new(AshikhminShirley {
                rd: [1.0; 3],
                rs: [0.0; 3],
                nu: 10.0,
                nv: 10.0,
            }),
        ];
        for m in conserving {
            for deg in [0.0f64, 30.0, 60.0, 80.0, 89.0] {
                let a = directional_albedo(m.as_ref(), deg.to_radians(), 128, 256);
                for v in a {
                    assert!(v <= 1.0 + 2e-3, "{} albedo {v} at {deg}°", m.name());
                }
            }
        }
    }

    #[test]
    fn lambert_albedo_equals_kd() {
        let m = Lambert {
            kd: [0.8, 0.5, 0.2],
        };
        for deg in [0.0f64, 45.0, 85.0] {
            let a = directional_albedo(&m, deg.to_radians(), 256, 256);
            for c in 0..3 {
                assert!((a[c] - m.kd[c]).abs() < 2e-3 * m.kd[c], "{a:?}");
            }
        }
    }

    #[test]
    fn phong_albedo_at_normal_incidence_is_kd_plus_ks() {
        // The lobe around the normal integrates in closed form to ks at θi = 0.
        let m = Phong {
            kd: [0.2; 3],
            ks: [0.7; 3],
            exponent: 20.0,
        };
        let a = directional_albedo(&m, 0.0, 512, 128);
        assert!((a[0] - 0.9).abs() < 2e-3, "{a:?}");
    }

    #[test]
    fn microfacet_distributions_are_normalised() {
        // ∫ D(h) cos θh dω = 2π ∫₀^{π/2} D(θ) cos θ sin θ dθ, by the midpoint rule in u = cos² θ.
        let integrate = |d: &dyn MicrofacetDistribution| {
            let n = 400_000;
            let mut s = 0.0;
            for i in 0..n {
                let u = (i as f64 + 0.5) / n as f64; // u = cos²θ, du = -2 cos θ sin θ dθ
                s += d.d(u.sqrt());
            }
            PI * s / n as f64
        };
        for m in [0.05, 0.2, 0.7] {
            let v = integrate(&Beckmann { m });
            assert!((v - 1.0).abs() < 1e-3, "beckmann m={m}: {v}");
        }
        for alpha in [0.05, 0.2, 0.7] {
            let v = integrate(&TrowbridgeReitz { alpha });
            assert!((v - 1.0).abs() < 1e-3, "ggx α={alpha}: {v}");
        }
        for exponent in [1.0, 50.0, 1000.0] {
            let v = integrate(&BlinnDistribution { exponent });
            assert!((v - 1.0).abs() < 1e-3, "blinn n={exponent}: {v}");
        }
    }

    #[test]
    fn fresnel_limits() {
        // Normal incidence: ((η-1)/(η+1))²; grazing: 1.
        let f0 = fresnel_dielectric(1.0, 1.5);
        assert!((f0 - 0.04).abs() < 1e-12);
        assert!((fresnel_dielectric(1e-9, 1.5) - 1.0).abs() < 1e-6);
        assert!((fresnel_schlick(1.0, 0.04) - 0.04).abs() < 1e-15);
    }

    #[test]
    fn invalid_parameters_are_rejected() {
        assert!(Lambert {
            kd: [f64::NAN, 0.0, 0.0]
        }
        .validate()
        .is_err());
        assert!(Ggx {
            kd: [0.0; 3],
            ks: [1.0; 3],
            alpha: -1.0,
            ior: 1.5
        }
        .validate()
        .is_err());
        assert!(Phong {
            kd: [0.5; 3],
            ks: [0.5; 3],
            exponent: 10.0
        }
        .validate()
        .is_ok());
    }
}
