//! Analytic reflectance models, all behind the [`Brdf`] trait.
//!
//! Every model returns zero below the horizon and is reciprocal. Colour parameters are RGB.
//! Models that promise energy conservation (directional albedo ≤ 1) say so, with the condition.
//!
//! Each model is one type, generic over its scalar `T` ([`Real`]; `f64` by default) and written
//! once as [`Analytic::value`] over any [`PairGeometry`]. On `f64` with a [`Pair`] it is the
//! [`Brdf`] a renderer evaluates; on [`crate::real::Dual`] numbers with a precomputed [`Geom`]
//! it gives the exact parameter gradients the `fit` crate's solver needs.

use crate::coords::Vec3;
use crate::error::{BrdfError, Result};
use crate::real::Real;
use crate::sample::{
    cosine_pdf, cosine_sample, ggx_visible_normal, half_vector, pick_component, reflect,
};
use crate::{cosine_hemisphere, cosine_hemisphere_pdf, Brdf, DirectionSample, Rgb};
use std::f64::consts::{FRAC_1_PI, PI};

pub mod geometry;
pub mod htsg;
pub use geometry::{Geom, Pair, PairGeometry};
pub use htsg::Htsg;

/// A model evaluated over the scalar `T` at any direction-pair geometry.
pub trait Analytic<T: Real> {
    /// The RGB value at a direction pair whose two directions lie above the horizon.
    fn value<G: PairGeometry>(&self, g: &G) -> [T; 3];
}

fn below(wi: &Vec3, wo: &Vec3) -> bool {
    wi.z <= 0.0 || wo.z <= 0.0
}

/// kd/π per channel.
fn diffuse<T: Real>(kd: &[T; 3]) -> [T; 3] {
    [kd[0] * FRAC_1_PI, kd[1] * FRAC_1_PI, kd[2] * FRAC_1_PI]
}

/// `a + b · s` per channel.
fn add_scaled<T: Real>(a: [T; 3], b: &[T; 3], s: T) -> [T; 3] {
    [a[0] + b[0] * s, a[1] + b[1] * s, a[2] + b[2] * s]
}

/// Implements [`Brdf`] for the `f64` form of a model: zero below the horizon, else
/// [`Analytic::value`] at the [`Pair`]; with `sampled`, direction sampling by the model's
/// [`LobeSampler`].
macro_rules! analytic_brdf {
    ($model:ident, $name:literal $(, |$m:ident| $isotropic:expr)? $(, $sampled:ident)?) => {
        impl Brdf for $model {
            fn eval(&self, wi: &Vec3, wo: &Vec3) -> Rgb {
                if below(wi, wo) {
                    return [0.0; 3];
                }
                self.value(&Pair::new(wi, wo))
            }
            fn name(&self) -> String {
                $name.into()
            }
            $(
                fn is_isotropic(&self) -> bool {
                    let $m = self;
                    $isotropic
                }
            )?
            $(
                fn sample(&self, wo: &Vec3, u: [f64; 3]) -> Option<DirectionSample> {
                    let _ = stringify!($sampled);
                    LobeSampler::sample_lobes(self, wo, u)
                }
                fn pdf(&self, wi: &Vec3, wo: &Vec3) -> f64 {
                    LobeSampler::lobes_pdf(self, wi, wo)
                }
                fn has_importance_sampler(&self) -> bool {
                    true
                }
            )?
        }
    };
}
pub(crate) use analytic_brdf;

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
pub fn fresnel_dielectric<T: Real>(cos_i: f64, eta: T) -> T {
    let c = cos_i.abs().min(1.0);
    let g2 = eta * eta - 1.0 + c * c;
    if g2.val() <= 0.0 {
        return T::cst(1.0);
    }
    let g = g2.sqrt();
    let a = (g - c) / (g + c);
    let b = ((g + c) * c - 1.0) / ((g - c) * c + 1.0);
    a * 0.5 * a * (b * b + 1.0)
}

/// Schlick's approximation of Fresnel reflectance with normal-incidence reflectance `f0`.
pub fn fresnel_schlick<T: Real>(cos_i: f64, f0: T) -> T {
    schlick(geometry::schlick_weight(cos_i), f0)
}

/// Schlick's Fresnel term with the grazing weight `w` = (1 − cos θ)⁵.
fn schlick<T: Real>(w: f64, f0: T) -> T {
    f0 + (-f0 + 1.0) * w
}

/// Direction sampling that follows a model's own lobes: the [`Brdf::sample`] and [`Brdf::pdf`]
/// of the models that have one.
trait LobeSampler {
    fn sample_lobes(&self, wo: &Vec3, u: [f64; 3]) -> Option<DirectionSample>;
    fn lobes_pdf(&self, wi: &Vec3, wo: &Vec3) -> f64;
}

/// Lambert: cosine-weighted sampling, exact (f cos θ / pdf = kd).
impl LobeSampler for Lambert {
    fn sample_lobes(&self, wo: &Vec3, u: [f64; 3]) -> Option<DirectionSample> {
        cosine_sample(wo, u)
    }
    fn lobes_pdf(&self, wi: &Vec3, wo: &Vec3) -> f64 {
        cosine_pdf(wi, wo)
    }
}

/// The diffuse-plus-GGX mixture sampler of [`Ggx`] and [`GgxTwoLobe`]: the diffuse term
/// cosine-weighted, each GGX lobe by its visible normals, chosen in proportion to the mean
/// diffuse albedo and to each lobe's mean scale times the Fresnel reflectance at `wo`.
struct GgxMixture<'a, const K: usize> {
    kd: &'a Rgb,
    ks: &'a [Rgb; K],
    alpha: &'a [f64; K],
    ior: f64,
}

impl<const K: usize> GgxMixture<'_, K> {
    /// Selection weights (diffuse first, then each lobe) for the outgoing direction `wo`.
    fn weights(&self, wo: &Vec3) -> ([f64; 3], f64) {
        let mean = |c: &Rgb| (c[0] + c[1] + c[2]).max(0.0) / 3.0;
        let f = fresnel_dielectric(wo.z, self.ior);
        let mut w = [0.0; 3];
        w[0] = mean(self.kd);
        for k in 0..K {
            w[k + 1] = mean(&self.ks[k]) * f;
        }
        let total: f64 = w.iter().sum();
        if total > 0.0 && total.is_finite() {
            (w, total)
        } else {
            // a black material: any density will do, the cosine one is cheapest
            ([1.0, 0.0, 0.0], 1.0)
        }
    }

    fn sample(&self, wo: &Vec3, u: [f64; 3]) -> Option<DirectionSample> {
        if wo.z <= 0.0 {
            return None;
        }
        let (w, _) = self.weights(wo);
        let wi = match pick_component(&w[..K + 1], u[0]) {
            0 => cosine_hemisphere(u[1], u[2]),
            k => reflect(wo, &ggx_visible_normal(self.alpha[k - 1], wo, u[1], u[2])),
        };
        if wi.z <= 0.0 {
            return None;
        }
        let pdf = self.pdf(&wi, wo);
        (pdf > 0.0 && pdf.is_finite()).then_some(DirectionSample { wi, pdf })
    }

    fn pdf(&self, wi: &Vec3, wo: &Vec3) -> f64 {
        if wi.z <= 0.0 || wo.z <= 0.0 {
            return 0.0;
        }
        let (w, total) = self.weights(wo);
        let mut p = w[0] * cosine_hemisphere_pdf(wi);
        if let Some(h) = half_vector(wi, wo) {
            for k in 0..K {
                if w[k + 1] > 0.0 {
                    p += w[k + 1] * ggx_reflection_pdf(self.alpha[k], wo, &h);
                }
            }
        }
        p / total
    }
}

/// Density in solid angle of the reflected direction when the microfacet normal `h` is drawn
/// from the GGX visible normals of `wo`: G₁(wo) D(h) / (4 cos θo).
fn ggx_reflection_pdf(alpha: f64, wo: &Vec3, h: &Vec3) -> f64 {
    let dist = TrowbridgeReitz { alpha };
    let g1 = 1.0 / (1.0 + dist.lambda(wo.z));
    g1 * dist.d(h.z) / (4.0 * wo.z)
}

impl LobeSampler for Ggx {
    fn sample_lobes(&self, wo: &Vec3, u: [f64; 3]) -> Option<DirectionSample> {
        self.mixture().sample(wo, u)
    }
    fn lobes_pdf(&self, wi: &Vec3, wo: &Vec3) -> f64 {
        self.mixture().pdf(wi, wo)
    }
}

impl Ggx {
    fn mixture(&self) -> GgxMixture<'_, 1> {
        GgxMixture {
            kd: &self.kd,
            ks: std::array::from_ref(&self.ks),
            alpha: std::array::from_ref(&self.alpha),
            ior: self.ior,
        }
    }
}

impl LobeSampler for GgxTwoLobe {
    fn sample_lobes(&self, wo: &Vec3, u: [f64; 3]) -> Option<DirectionSample> {
        self.mixture().sample(wo, u)
    }
    fn lobes_pdf(&self, wi: &Vec3, wo: &Vec3) -> f64 {
        self.mixture().pdf(wi, wo)
    }
}

impl GgxTwoLobe {
    fn mixture(&self) -> GgxMixture<'_, 2> {
        GgxMixture {
            kd: &self.kd,
            ks: &self.ks,
            alpha: &self.alpha,
            ior: self.ior,
        }
    }
}

/// An isotropic microfacet normal distribution, normalised so that ∫ D(h) cos θh dω = 1.
pub trait MicrofacetDistribution<T: Real = f64> {
    /// Density of microfacet normals at polar angle with cosine `cos_h`.
    fn d(&self, cos_h: f64) -> T;
}

/// Beckmann distribution with RMS slope `m`.
#[derive(Debug, Clone, Copy)]
pub struct Beckmann<T: Real = f64> {
    /// RMS slope of the microfacets.
    pub m: T,
}

impl<T: Real> Beckmann<T> {
    /// The density at a half vector with tan² θh = `tan2_h` and cos⁴ θh = `cos4_h`.
    pub fn density(&self, tan2_h: f64, cos4_h: f64) -> T {
        let m2 = self.m * self.m;
        (-(T::cst(tan2_h) / m2)).exp() / (m2 * (PI * cos4_h))
    }
}

impl<T: Real> MicrofacetDistribution<T> for Beckmann<T> {
    fn d(&self, cos_h: f64) -> T {
        if cos_h <= 0.0 {
            return T::cst(0.0);
        }
        let c2 = cos_h * cos_h;
        self.density((1.0 - c2) / c2, c2 * c2)
    }
}

/// GGX / Trowbridge-Reitz distribution with roughness `alpha`.
#[derive(Debug, Clone, Copy)]
pub struct TrowbridgeReitz<T: Real = f64> {
    /// Width parameter α.
    pub alpha: T,
}

impl<T: Real> MicrofacetDistribution<T> for TrowbridgeReitz<T> {
    fn d(&self, cos_h: f64) -> T {
        if cos_h <= 0.0 {
            return T::cst(0.0);
        }
        let c2 = cos_h * cos_h;
        let a2 = self.alpha * self.alpha;
        let t = (a2 - 1.0) * c2 + 1.0;
        a2 / (t * t * PI)
    }
}

impl<T: Real> TrowbridgeReitz<T> {
    /// Smith's Λ for a direction with cosine `cos_t` to the normal.
    pub fn lambda(&self, cos_t: f64) -> T {
        self.lambda_of_tan2(geometry::tan2(cos_t))
    }

    /// Smith's Λ for a direction with tan² θ = `tan2`.
    pub fn lambda_of_tan2(&self, tan2: f64) -> T {
        ((self.alpha * self.alpha * tan2 + 1.0).sqrt() - 1.0) * 0.5
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
pub struct Lambert<T: Real = f64> {
    /// Diffuse albedo per channel, in `[0, 1]` for a physical surface.
    pub kd: [T; 3],
}

impl Lambert {
    /// Checks the parameters.
    pub fn validate(&self) -> Result<()> {
        check_rgb("lambert", "kd", &self.kd, 0.0, 1.0)
    }
}

impl<T: Real> Analytic<T> for Lambert<T> {
    fn value<G: PairGeometry>(&self, _: &G) -> [T; 3] {
        diffuse(&self.kd)
    }
}

analytic_brdf!(Lambert, "lambert", sampled);

/// The modified Phong model (Lafortune & Willems 1994): kd/π + ks (n+2)/(2π) cosⁿ α, with α
/// the angle between ωo and the mirror direction of ωi. Reciprocal, and energy conserving when
/// kd + ks ≤ 1 per channel.
#[derive(Debug, Clone, PartialEq)]
pub struct Phong<T: Real = f64> {
    /// Diffuse albedo.
    pub kd: [T; 3],
    /// Specular albedo at normal incidence.
    pub ks: [T; 3],
    /// Specular exponent n ≥ 0.
    pub exponent: T,
}

impl Phong {
    /// Checks the parameters.
    pub fn validate(&self) -> Result<()> {
        check_rgb("phong", "kd", &self.kd, 0.0, 1.0)?;
        check_rgb("phong", "ks", &self.ks, 0.0, 1.0)?;
        check_param("phong", "n", self.exponent, 0.0, 1e7)
    }
}

/// kd/π + ks (n + k)/(kπ) cosⁿ: a normalised cosine lobe (Phong: k = 2, Blinn-Phong: k = 8).
fn cosine_lobe<T: Real>(kd: &[T; 3], ks: &[T; 3], n: T, k: f64, cos: f64) -> [T; 3] {
    let s = (n + k) / (k * PI) * T::cst(cos).powf(n);
    add_scaled(diffuse(kd), ks, s)
}

impl<T: Real> Analytic<T> for Phong<T> {
    fn value<G: PairGeometry>(&self, g: &G) -> [T; 3] {
        cosine_lobe(&self.kd, &self.ks, self.exponent, 2.0, g.mirror())
    }
}

analytic_brdf!(Phong, "phong");

/// Blinn-Phong: kd/π + ks (n+8)/(8π) cosⁿ θh (the usual approximate normalisation).
#[derive(Debug, Clone, PartialEq)]
pub struct BlinnPhong<T: Real = f64> {
    /// Diffuse albedo.
    pub kd: [T; 3],
    /// Specular coefficient.
    pub ks: [T; 3],
    /// Exponent n ≥ 0.
    pub exponent: T,
}

impl BlinnPhong {
    /// Checks the parameters.
    pub fn validate(&self) -> Result<()> {
        check_rgb("blinn", "kd", &self.kd, 0.0, 1.0)?;
        check_rgb("blinn", "ks", &self.ks, 0.0, 1.0)?;
        check_param("blinn", "n", self.exponent, 0.0, 1e7)
    }
}

impl<T: Real> Analytic<T> for BlinnPhong<T> {
    fn value<G: PairGeometry>(&self, g: &G) -> [T; 3] {
        cosine_lobe(&self.kd, &self.ks, self.exponent, 8.0, g.h_z())
    }
}

analytic_brdf!(BlinnPhong, "blinn");

/// One lobe of the Lafortune model: ρ · max(0, Cx ux vx + Cy uy vy + Cz uz vz)ⁿ.
#[derive(Debug, Clone, PartialEq)]
pub struct LafortuneLobe<T: Real = f64> {
    /// Cx (negative for a forward-scattering lobe).
    pub cx: T,
    /// Cy (equal to Cx for an isotropic lobe).
    pub cy: T,
    /// Cz.
    pub cz: T,
    /// Exponent n.
    pub exponent: T,
    /// Lobe albedo factor per channel.
    pub rho: [T; 3],
}

/// The multi-lobe Lafortune model: kd/π + Σ lobes.
#[derive(Debug, Clone, PartialEq)]
pub struct Lafortune<T: Real = f64> {
    /// Diffuse albedo.
    pub kd: [T; 3],
    /// Generalised cosine lobes.
    pub lobes: Vec<LafortuneLobe<T>>,
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

impl<T: Real> Analytic<T> for Lafortune<T> {
    fn value<G: PairGeometry>(&self, g: &G) -> [T; 3] {
        let mut out = diffuse(&self.kd);
        for l in &self.lobes {
            let base = l.cx * g.xx() + l.cy * g.yy() + l.cz * g.zz();
            if base.val() > 0.0 {
                let s = base.powf(l.exponent);
                for c in 0..3 {
                    // A channel the lobe leaves dark adds nothing (not 0 · ∞ where sⁿ overflows).
                    if !l.rho[c].is_zero() {
                        out[c] = out[c] + l.rho[c] * s;
                    }
                }
            }
        }
        out
    }
}

analytic_brdf!(Lafortune, "lafortune", |m| m
    .lobes
    .iter()
    .all(|l| l.cx == l.cy));

/// Ward's model: kd/π + ks exp(−tan²θh (cos²φh/αx² + sin²φh/αy²)) / (4π αx αy √(cos θi cos θo)).
/// Isotropic when αx = αy. Not energy conserving at grazing angles.
#[derive(Debug, Clone, PartialEq)]
pub struct Ward<T: Real = f64> {
    /// Diffuse albedo.
    pub kd: [T; 3],
    /// Specular albedo.
    pub ks: [T; 3],
    /// Roughness along the tangent x.
    pub alpha_x: T,
    /// Roughness along the tangent y.
    pub alpha_y: T,
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

impl<T: Real> Analytic<T> for Ward<T> {
    fn value<G: PairGeometry>(&self, g: &G) -> [T; 3] {
        let (ax, ay) = (self.alpha_x, self.alpha_y);
        let (t2, c2) = (g.tan2_h(), g.cos2_phi_h());
        let e = T::cst(t2 * c2) / (ax * ax) + T::cst(t2 * (1.0 - c2)) / (ay * ay);
        let s = (-e).exp() / (ax * ay * (4.0 * PI * g.sqrt_zz()));
        add_scaled(diffuse(&self.kd), &self.ks, s)
    }
}

analytic_brdf!(Ward, "ward", |m| m.alpha_x == m.alpha_y);

/// Beckmann D · G / (4 cos θi cos θo) with the V-cavity G: a Cook-Torrance lobe without its
/// Fresnel factor.
fn beckmann_lobe<T: Real, G: PairGeometry>(m: T, g: &G) -> T {
    Beckmann { m }.density(g.tan2_h(), g.h_z4()) * (g.v_cavity() / (4.0 * g.zz()))
}

/// GGX D · G₂ / (4 cos θi cos θo) with Smith height-correlated G₂: a GGX lobe without its
/// Fresnel factor.
fn ggx_lobe<T: Real, G: PairGeometry>(alpha: T, g: &G) -> T {
    let dist = TrowbridgeReitz { alpha };
    let g2 =
        T::cst(1.0) / (dist.lambda_of_tan2(g.tan2_i()) + 1.0 + dist.lambda_of_tan2(g.tan2_o()));
    dist.d(g.h_z()) * g2 / (4.0 * g.zz())
}

/// kd/π + Σₖ ksₖ lobeₖ F: the diffuse-plus-microfacet form shared by Cook-Torrance and GGX with
/// one or two lobes, F the exact Fresnel term of index `ior`.
fn microfacet<T: Real, G: PairGeometry, const K: usize>(
    kd: &[T; 3],
    ks: &[[T; 3]; K],
    lobes: [T; K],
    ior: T,
    g: &G,
) -> [T; 3] {
    let f = fresnel_dielectric(g.cos_d(), ior);
    let mut out = diffuse(kd);
    for k in 0..K {
        out = add_scaled(out, &ks[k], lobes[k] * f);
    }
    out
}

/// Cook-Torrance: kd/π + ks D F G / (4 cos θi cos θo) with the Beckmann distribution, the exact
/// dielectric Fresnel term and the V-cavity shadowing-masking term. With kd + ks ≤ 1 the albedo
/// stays ≤ 1.
#[derive(Debug, Clone, PartialEq)]
pub struct CookTorrance<T: Real = f64> {
    /// Diffuse albedo.
    pub kd: [T; 3],
    /// Specular scale.
    pub ks: [T; 3],
    /// Beckmann RMS slope.
    pub m: T,
    /// Relative index of refraction for the Fresnel term.
    pub ior: T,
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

impl<T: Real> Analytic<T> for CookTorrance<T> {
    fn value<G: PairGeometry>(&self, g: &G) -> [T; 3] {
        let lobe = beckmann_lobe(self.m, g);
        microfacet(&self.kd, &[self.ks], [lobe], self.ior, g)
    }
}

analytic_brdf!(CookTorrance, "cook-torrance");

/// GGX (Trowbridge-Reitz) microfacet model with Smith height-correlated masking-shadowing and the
/// exact dielectric Fresnel term: kd/π + ks D F G₂ / (4 cos θi cos θo). With kd + ks ≤ 1 the
/// albedo stays ≤ 1.
#[derive(Debug, Clone, PartialEq)]
pub struct Ggx<T: Real = f64> {
    /// Diffuse albedo.
    pub kd: [T; 3],
    /// Specular scale.
    pub ks: [T; 3],
    /// Roughness α.
    pub alpha: T,
    /// Relative index of refraction.
    pub ior: T,
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

impl<T: Real> Analytic<T> for Ggx<T> {
    fn value<G: PairGeometry>(&self, g: &G) -> [T; 3] {
        let lobe = ggx_lobe(self.alpha, g);
        microfacet(&self.kd, &[self.ks], [lobe], self.ior, g)
    }
}

analytic_brdf!(Ggx, "ggx", sampled);

/// The Oren-Nayar model (qualitative form) of a rough diffuse surface with facet slope deviation
/// σ (radians).
#[derive(Debug, Clone, PartialEq)]
pub struct OrenNayar<T: Real = f64> {
    /// Albedo of the facets.
    pub albedo: [T; 3],
    /// Standard deviation of facet slope angles, radians.
    pub sigma: T,
}

impl OrenNayar {
    /// Checks the parameters.
    pub fn validate(&self) -> Result<()> {
        check_rgb("oren-nayar", "albedo", &self.albedo, 0.0, 1.0)?;
        check_param("oren-nayar", "sigma", self.sigma, 0.0, PI / 2.0)
    }
}

impl<T: Real> Analytic<T> for OrenNayar<T> {
    fn value<G: PairGeometry>(&self, g: &G) -> [T; 3] {
        let s2 = self.sigma * self.sigma;
        let a = -(s2 * 0.5 / (s2 + 0.33)) + 1.0;
        let b = s2 * 0.45 / (s2 + 0.09);
        let k = (a + b * g.oren_nayar()) * FRAC_1_PI;
        let albedo = &self.albedo;
        [albedo[0] * k, albedo[1] * k, albedo[2] * k]
    }
}

analytic_brdf!(OrenNayar, "oren-nayar");

/// The Ashikhmin-Shirley model: a coupled diffuse term and an anisotropic Phong-like specular
/// lobe with Schlick Fresnel, designed to conserve energy.
#[derive(Debug, Clone, PartialEq)]
pub struct AshikhminShirley<T: Real = f64> {
    /// Diffuse reflectance Rd.
    pub rd: [T; 3],
    /// Specular reflectance at normal incidence Rs.
    pub rs: [T; 3],
    /// Exponent along the tangent x.
    pub nu: T,
    /// Exponent along the tangent y.
    pub nv: T,
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

impl<T: Real> Analytic<T> for AshikhminShirley<T> {
    fn value<G: PairGeometry>(&self, g: &G) -> [T; 3] {
        let (nu, nv) = (self.nu, self.nv);
        let c2 = g.cos2_phi_h();
        let lobe = T::cst(g.h_z()).powf(nu * c2 + nv * (1.0 - c2));
        let spec_norm = ((nu + 1.0) * (nv + 1.0)).sqrt() / (8.0 * PI);
        let spec = spec_norm * lobe / g.as_denominator();
        let (w, angular) = (g.schlick5(), 28.0 / (23.0 * PI) * g.as_diffuse());
        let mut out = [T::cst(0.0); 3];
        for c in 0..3 {
            let (rd, rs) = (self.rd[c], self.rs[c]);
            out[c] = rd * (-rs + 1.0) * angular + spec * schlick(w, rs);
        }
        out
    }
}

analytic_brdf!(AshikhminShirley, "ashikhmin-shirley", |m| m.nu == m.nv);

/// Two-lobe GGX: kd/π + Σₖ ksₖ Dₖ F G₂ₖ / (4 cos θi cos θo), two [`Ggx`] specular lobes of
/// different roughness sharing one Fresnel index (a sharp coat over a broader base, or the
/// two-scale roughness of many metals). With kd + ks₁ + ks₂ ≤ 1 the albedo stays ≤ 1.
#[derive(Debug, Clone, PartialEq)]
pub struct GgxTwoLobe<T: Real = f64> {
    /// Diffuse albedo.
    pub kd: [T; 3],
    /// Specular scale of each lobe.
    pub ks: [[T; 3]; 2],
    /// Roughness α of each lobe.
    pub alpha: [T; 2],
    /// Relative index of refraction shared by both lobes.
    pub ior: T,
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

impl<T: Real> Analytic<T> for GgxTwoLobe<T> {
    fn value<G: PairGeometry>(&self, g: &G) -> [T; 3] {
        let lobes = self.alpha.map(|a| ggx_lobe(a, g));
        microfacet(&self.kd, &self.ks, lobes, self.ior, g)
    }
}

analytic_brdf!(GgxTwoLobe, "ggx2", sampled);

/// Two-lobe Cook-Torrance: kd/π + Σₖ ksₖ Dₖ F G / (4 cos θi cos θo), two Beckmann lobes of
/// different RMS slope sharing one Fresnel index. With kd + ks₁ + ks₂ ≤ 1 the albedo stays ≤ 1.
#[derive(Debug, Clone, PartialEq)]
pub struct CookTorranceTwoLobe<T: Real = f64> {
    /// Diffuse albedo.
    pub kd: [T; 3],
    /// Specular scale of each lobe.
    pub ks: [[T; 3]; 2],
    /// Beckmann RMS slope of each lobe.
    pub m: [T; 2],
    /// Relative index of refraction shared by both lobes.
    pub ior: T,
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

impl<T: Real> Analytic<T> for CookTorranceTwoLobe<T> {
    fn value<G: PairGeometry>(&self, g: &G) -> [T; 3] {
        let lobes = self.m.map(|m| beckmann_lobe(m, g));
        microfacet(&self.kd, &self.ks, lobes, self.ior, g)
    }
}

analytic_brdf!(CookTorranceTwoLobe, "ct2");

#[cfg(test)]
mod tests {
    use super::*;
    use crate::coords::Spherical;
    use crate::summary::directional_albedo;
    use rand::{Rng, SeedableRng};

    /// A model as a [`Brdf`] and evaluated at cached geometry.
    pub(crate) trait Model: Brdf {
        fn cached(&self, g: &Geom) -> Rgb;
    }

    impl<M: Analytic<f64> + Brdf> Model for M {
        fn cached(&self, g: &Geom) -> Rgb {
            self.value(g)
        }
    }

    pub(crate) fn all_models() -> Vec<Box<dyn Model>> {
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

    /// Calls `check` with every model of [`all_models`] and `n` seeded random direction pairs.
    fn for_random_pairs(seed: u64, n: usize, mut check: impl FnMut(&dyn Model, Vec3, Vec3)) {
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed);
        for m in all_models() {
            for _ in 0..n {
                let (wi, wo) = (random_dir(&mut rng), random_dir(&mut rng));
                check(m.as_ref(), wi, wo);
            }
        }
    }

    #[test]
    fn every_model_is_reciprocal_and_non_negative() {
        for_random_pairs(11, 5000, |m, wi, wo| {
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
        });
    }

    #[test]
    fn cached_geometry_gives_the_values_of_the_pair() {
        for_random_pairs(12, 500, |m, wi, wo| {
            if let Some(g) = Geom::new(&wi, &wo) {
                assert_eq!(m.cached(&g), m.eval(&wi, &wo), "{}", m.name());
            }
        });
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

    /// The models with their own sampler, over a range of lobes: diffuse, plastics, a metal-like
    /// index, two lobes, a broad lobe with α > 1.
    fn sampled_models() -> Vec<(String, Box<dyn Brdf>)> {
        let mut out: Vec<(String, Box<dyn Brdf>)> = vec![(
            "lambert".into(),
            Box::new(Lambert {
                kd: [0.2, 0.5, 0.8],
            }),
        )];
        for (alpha, kd, ior) in [
            (0.1, 0.0, 60.0),
            (0.3, 0.4, 1.5),
            (0.8, 0.1, 3.0),
            (1.6, 0.0, 1.5),
        ] {
            out.push((
                format!("ggx α={alpha} kd={kd} ior={ior}"),
                Box::new(Ggx {
                    kd: [kd; 3],
                    ks: [0.9, 0.7, 0.5],
                    alpha,
                    ior,
                }),
            ));
        }
        out.push((
            "ggx2".into(),
            Box::new(GgxTwoLobe {
                kd: [0.3, 0.2, 0.1],
                ks: [[0.5; 3], [0.4; 3]],
                alpha: [0.12, 0.6],
                ior: 1.5,
            }),
        ));
        out
    }

    #[test]
    fn samplers_report_the_density_their_pdf_gives() {
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(21);
        for (name, m) in sampled_models() {
            assert!(m.has_importance_sampler(), "{name}");
            for _ in 0..3000 {
                let wo = Spherical::new(
                    rng.gen_range(0.0..1.55),
                    rng.gen_range(0.0..std::f64::consts::TAU),
                )
                .to_vector();
                let Some(s) = m.sample(&wo, rng.gen()) else {
                    continue;
                };
                assert!(s.wi.z > 0.0 && (s.wi.norm() - 1.0).abs() < 1e-9, "{name}");
                let p = m.pdf(&s.wi, &wo);
                assert!(
                    (s.pdf - p).abs() <= 1e-9 * p,
                    "{name}: sampled density {} but pdf {p}",
                    s.pdf
                );
            }
            let below = Vec3::new(0.0, 0.6, -0.8);
            assert!(m.sample(&below, [0.5; 3]).is_none(), "{name}");
            assert_eq!(m.pdf(&Vec3::z(), &below), 0.0, "{name}");
            assert_eq!(m.pdf(&below, &Vec3::z()), 0.0, "{name}");
        }
    }

    /// ∫ pdf dωi over the upper hemisphere (by the albedo quadrature, an independent rule) equals
    /// the fraction of draws that stay above the horizon: the density is the sampler's.
    #[test]
    fn sampler_densities_integrate_to_the_fraction_of_draws_kept() {
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(8);
        for (name, m) in sampled_models() {
            for theta_o in [0.0, 0.7, 1.3] {
                let wo = Spherical::new(theta_o, 0.0).to_vector();
                let (n_u, n_phi) = (600, 600);
                let integral: f64 = (0..n_u)
                    .flat_map(|iu| crate::summary::albedo_cells(theta_o, n_u, n_phi, iu))
                    .map(|(wi, w)| m.pdf(&wi, &wo) * w / wi.z)
                    .sum();
                let n = 40_000;
                let kept = (0..n)
                    .filter(|_| m.sample(&wo, rng.gen()).is_some())
                    .count();
                let kept = kept as f64 / n as f64;
                assert!(
                    integral <= 1.0 + 5e-3,
                    "{name} θo={theta_o}: ∫pdf = {integral}"
                );
                assert!(
                    (integral - kept).abs() < 0.01,
                    "{name} θo={theta_o}: ∫pdf = {integral}, draws kept {kept}"
                );
            }
        }
    }

    /// The importance-sampled estimate of the directional albedo agrees with the quadrature of
    /// `brdf::directional_albedo`, and for Lambert every sample carries exactly kd.
    #[test]
    fn importance_sampled_albedo_matches_the_quadrature() {
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(13);
        for (name, m) in sampled_models() {
            for theta_o in [0.2, 0.9, 1.35] {
                let wo = Spherical::new(theta_o, 0.0).to_vector();
                let reference = directional_albedo(m.as_ref(), theta_o, 512, 512);
                let n = 60_000;
                let mut sum = [0.0; 3];
                let mut sum2 = [0.0; 3];
                for _ in 0..n {
                    let Some(s) = m.sample(&wo, rng.gen()) else {
                        continue;
                    };
                    let f = m.eval(&s.wi, &wo);
                    for c in 0..3 {
                        let x = f[c] * s.wi.z / s.pdf;
                        sum[c] += x;
                        sum2[c] += x * x;
                    }
                }
                for c in 0..3 {
                    let mean = sum[c] / n as f64;
                    let sd = ((sum2[c] / n as f64 - mean * mean).max(0.0) / n as f64).sqrt();
                    let tol = 5.0 * sd + 2e-3 * reference[c] + 1e-6;
                    assert!(
                        (mean - reference[c]).abs() < tol,
                        "{name} θo={theta_o} channel {c}: sampled {mean} ± {sd}, quadrature {}",
                        reference[c]
                    );
                    if name == "lambert" {
                        assert!(
                            sd < 1e-12,
                            "{name}: the cosine sampler is exact for Lambert"
                        );
                    }
                }
            }
        }
    }

    #[test]
    fn models_without_a_sampler_draw_cosine_weighted_directions() {
        let m = Phong {
            kd: [0.3; 3],
            ks: [0.5; 3],
            exponent: 20.0,
        };
        assert!(!m.has_importance_sampler());
        let wo = Spherical::new(0.4, 0.0).to_vector();
        let s = m.sample(&wo, [0.3, 0.6, 0.9]).unwrap();
        assert!((s.pdf - s.wi.z / PI).abs() < 1e-15);
        assert_eq!(m.pdf(&s.wi, &wo), s.pdf);
    }
}
