//! The fittable models: parameter layout, bounds, generic evaluation, start points and the
//! material spec of a parameter vector.
//!
//! Colour is per channel for the albedo-like parameters (diffuse, specular, lobe albedo); the
//! shape parameters (roughness, exponent, index of refraction, lobe direction) are shared by the
//! three channels, as a renderer uses them. Every model's evaluation here is checked against the
//! `brdf::analytic` model its spec string builds (see the tests).

use crate::dual::Real;
use crate::error::{FitError, Result};
use brdf::{Brdf, Rgb, Vec3};
use std::f64::consts::{FRAC_1_PI, FRAC_PI_2, PI};

/// A fittable analytic model.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord, serde::Serialize)]
pub enum ModelKind {
    /// Lambert: kd/π.
    Lambert,
    /// Oren-Nayar (qualitative): albedo, σ.
    OrenNayar,
    /// Blinn-Phong: kd, ks, n.
    BlinnPhong,
    /// Modified (energy-conserving) Phong: kd, ks, n.
    Phong,
    /// Isotropic Ward: kd, ks, α.
    Ward,
    /// Lafortune with one isotropic lobe plus diffuse.
    Lafortune1,
    /// Lafortune with two isotropic lobes plus diffuse.
    Lafortune2,
    /// The thesis's Lafortune form (§2.2.1, eq. 2.11): diffuse plus one isotropic lobe whose
    /// direction and exponent are fitted per colour channel (`kd`, `cx`, `n`, `rho` each RGB).
    LafortuneRgb,
    /// Cook-Torrance (Beckmann, exact Fresnel, V-cavity shadowing).
    CookTorrance,
    /// Cook-Torrance with two Beckmann lobes sharing the Fresnel index.
    CookTorrance2,
    /// GGX with Smith height-correlated masking and exact Fresnel.
    Ggx,
    /// GGX with two lobes sharing the Fresnel index.
    Ggx2,
    /// Isotropic Ashikhmin-Shirley.
    AshikhminShirley,
    /// He-Torrance-Sillion-Greenberg (thesis §2.2.2, [`brdf::analytic::htsg`]): uniform diffuse
    /// `kd`, directional-diffuse scale `ks`, roughness σ₀ and autocorrelation length τ (µm),
    /// index of refraction.
    Htsg,
}

/// How an unbounded solver variable maps to a bounded model parameter.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Bound {
    /// q = lo + (hi − lo) · sigmoid(p).
    Interval(f64, f64),
    /// q = lo + eᵖ.
    Above(f64),
}

impl Bound {
    /// The model parameter of solver variable `p`.
    pub fn to_model<T: Real>(self, p: T) -> T {
        // Far outside ±40 the maps are saturated; hold them there so that no trial step of the
        // solver overflows.
        let v = p.val();
        match self {
            Bound::Interval(lo, hi) if v.abs() > 40.0 => {
                T::cst(lo + (hi - lo) * f64::from(v > 0.0))
            }
            Bound::Interval(lo, hi) => p.sigmoid() * (hi - lo) + lo,
            Bound::Above(lo) if v > 40.0 => T::cst(40f64.exp() + lo),
            Bound::Above(lo) => p.exp() + lo,
        }
    }

    /// The solver variable of model parameter `q` (clamped just inside the bounds).
    pub fn to_solver(self, q: f64) -> f64 {
        match self {
            Bound::Interval(lo, hi) => {
                let u = ((q - lo) / (hi - lo)).clamp(1e-6, 1.0 - 1e-6);
                (u / (1.0 - u)).ln()
            }
            Bound::Above(lo) => (q - lo).max(1e-12).ln(),
        }
    }
}

/// One model parameter: name in the spec string, bound, and default start value.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ParamDef {
    /// Key in the material spec (colour parameters take three consecutive slots).
    pub name: &'static str,
    /// Whether the parameter is an RGB colour (three slots) or a shared scalar.
    pub colour: bool,
    /// Bound enforced by reparameterisation.
    pub bound: Bound,
    /// Default start value (colour parameters: the same for all channels).
    pub start: f64,
    /// Typical range searched by the multi-start (solver space is sampled uniformly between the
    /// solver images of these two model values). Colour parameters keep their start.
    pub range: (f64, f64),
}

const fn colour(name: &'static str, hi: f64, start: f64) -> ParamDef {
    ParamDef {
        name,
        colour: true,
        bound: Bound::Interval(0.0, hi),
        start,
        range: (start, start),
    }
}

const fn shape(name: &'static str, bound: Bound, start: f64, range: (f64, f64)) -> ParamDef {
    ParamDef {
        name,
        colour: false,
        bound,
        start,
        range,
    }
}

const KD: ParamDef = colour("kd", 1.0, 0.2);
const KS: ParamDef = colour("ks", 1.0, 0.3);
const IOR: ParamDef = shape("ior", Bound::Interval(1.0, 60.0), 1.6, (1.2, 20.0));
const EXPONENT: ParamDef = shape("n", Bound::Above(0.0), 50.0, (2.0, 5000.0));

impl ModelKind {
    /// Every model, in table order.
    pub const ALL: [ModelKind; 14] = [
        ModelKind::Lambert,
        ModelKind::OrenNayar,
        ModelKind::BlinnPhong,
        ModelKind::Phong,
        ModelKind::Ward,
        ModelKind::Lafortune1,
        ModelKind::Lafortune2,
        ModelKind::LafortuneRgb,
        ModelKind::CookTorrance,
        ModelKind::CookTorrance2,
        ModelKind::Ggx,
        ModelKind::Ggx2,
        ModelKind::AshikhminShirley,
        ModelKind::Htsg,
    ];

    /// Short name used on the command line and in the study CSV.
    pub fn name(self) -> &'static str {
        match self {
            ModelKind::Lambert => "lambert",
            ModelKind::OrenNayar => "oren-nayar",
            ModelKind::BlinnPhong => "blinn",
            ModelKind::Phong => "phong",
            ModelKind::Ward => "ward",
            ModelKind::Lafortune1 => "lafortune",
            ModelKind::Lafortune2 => "lafortune2",
            ModelKind::LafortuneRgb => "lafortune-rgb",
            ModelKind::CookTorrance => "cook-torrance",
            ModelKind::CookTorrance2 => "cook-torrance2",
            ModelKind::Ggx => "ggx",
            ModelKind::Ggx2 => "ggx2",
            ModelKind::AshikhminShirley => "ashikhmin-shirley",
            ModelKind::Htsg => "htsg",
        }
    }

    /// The model named `name` with `lobes` specular lobes (1 or 2; only Lafortune, Cook-Torrance
    /// and GGX have a two-lobe variant). Accepts the spec aliases (`ct`, `on`, `as`, `blinn-phong`).
    pub fn parse(name: &str, lobes: usize) -> Result<ModelKind> {
        let base = match name.to_ascii_lowercase().as_str() {
            "lambert" => ModelKind::Lambert,
            "oren-nayar" | "on" => ModelKind::OrenNayar,
            "blinn" | "blinn-phong" => ModelKind::BlinnPhong,
            "phong" => ModelKind::Phong,
            "ward" => ModelKind::Ward,
            "lafortune" | "lafortune1" => ModelKind::Lafortune1,
            "lafortune2" => ModelKind::Lafortune2,
            "lafortune-rgb" => ModelKind::LafortuneRgb,
            "cook-torrance" | "ct" => ModelKind::CookTorrance,
            "cook-torrance2" | "ct2" => ModelKind::CookTorrance2,
            "ggx" => ModelKind::Ggx,
            "ggx2" => ModelKind::Ggx2,
            "ashikhmin-shirley" | "as" => ModelKind::AshikhminShirley,
            "htsg" | "he-torrance" => ModelKind::Htsg,
            other => return Err(FitError::UnknownModel(other.into())),
        };
        match (base, lobes) {
            (_, 1) => Ok(base),
            (ModelKind::Lafortune1 | ModelKind::Lafortune2, 2) => Ok(ModelKind::Lafortune2),
            (ModelKind::CookTorrance | ModelKind::CookTorrance2, 2) => Ok(ModelKind::CookTorrance2),
            (ModelKind::Ggx | ModelKind::Ggx2, 2) => Ok(ModelKind::Ggx2),
            _ => Err(FitError::UnknownModel(format!("{name} with {lobes} lobes"))),
        }
    }

    /// The parameter layout.
    pub fn params(self) -> Vec<ParamDef> {
        let lobe_t = |name| shape(name, Bound::Interval(-3.0, 3.0), -1.0, (-1.6, -0.7));
        let lobe_n = |name, start| shape(name, Bound::Above(0.0), start, (2.0, 2000.0));
        let rough = |name, start| shape(name, Bound::Interval(1e-3, 1.0), start, (0.01, 0.6));
        match self {
            ModelKind::Lambert => vec![colour("kd", 1.0, 0.5)],
            ModelKind::OrenNayar => vec![
                colour("albedo", 1.0, 0.5),
                shape("sigma", Bound::Interval(0.0, FRAC_PI_2), 0.3, (0.05, 1.2)),
            ],
            ModelKind::BlinnPhong | ModelKind::Phong => vec![KD, KS, EXPONENT],
            ModelKind::Ward => vec![KD, KS, rough("alpha", 0.1)],
            ModelKind::Lafortune1 => vec![
                KD,
                lobe_t("cx1"),
                lobe_n("n1", 30.0),
                colour("rho1", 1e4, 1.0),
            ],
            ModelKind::Lafortune2 => vec![
                KD,
                lobe_t("cx1"),
                lobe_n("n1", 200.0),
                colour("rho1", 1e4, 2.0),
                lobe_t("cx2"),
                lobe_n("n2", 10.0),
                colour("rho2", 1e4, 0.2),
            ],
            ModelKind::LafortuneRgb => vec![
                KD,
                ParamDef {
                    colour: true,
                    ..lobe_t("cx")
                },
                ParamDef {
                    colour: true,
                    ..lobe_n("n", 30.0)
                },
                colour("rho", 1e4, 1.0),
            ],
            ModelKind::CookTorrance => vec![KD, KS, rough("m", 0.15), IOR],
            ModelKind::Ggx => vec![KD, KS, rough("alpha", 0.15), IOR],
            ModelKind::CookTorrance2 => vec![
                KD,
                colour("ks1", 1.0, 0.3),
                rough("m1", 0.05),
                colour("ks2", 1.0, 0.2),
                rough("m2", 0.3),
                IOR,
            ],
            ModelKind::Ggx2 => vec![
                KD,
                colour("ks1", 1.0, 0.3),
                rough("alpha1", 0.05),
                colour("ks2", 1.0, 0.2),
                rough("alpha2", 0.3),
                IOR,
            ],
            ModelKind::AshikhminShirley => {
                vec![colour("rd", 1.0, 0.3), colour("rs", 1.0, 0.1), EXPONENT]
            }
            ModelKind::Htsg => vec![
                KD,
                colour("ks", 20.0, 1.0),
                shape("sigma", Bound::Interval(0.005, 5.0), 0.3, (0.03, 2.0)),
                shape("tau", Bound::Interval(0.1, 60.0), 4.0, (1.0, 20.0)),
                IOR,
            ],
        }
    }

    /// Number of solver variables (a colour parameter counts three).
    pub fn dimension(self) -> usize {
        self.params()
            .iter()
            .map(|p| if p.colour { 3 } else { 1 })
            .sum()
    }

    /// Model parameters (bounded) of a solver vector.
    pub fn to_model<T: Real>(self, p: &[T]) -> Vec<T> {
        let mut out = Vec::with_capacity(p.len());
        let mut k = 0;
        for d in self.params() {
            for _ in 0..if d.colour { 3 } else { 1 } {
                out.push(d.bound.to_model(p[k]));
                k += 1;
            }
        }
        out
    }

    /// Solver vector of model parameters `q`.
    pub fn to_solver(self, q: &[f64]) -> Vec<f64> {
        let mut out = Vec::with_capacity(q.len());
        let mut k = 0;
        for d in self.params() {
            for _ in 0..if d.colour { 3 } else { 1 } {
                out.push(d.bound.to_solver(q[k]));
                k += 1;
            }
        }
        out
    }

    /// The default start in model parameters, with the diffuse colour `kd` (per channel) taken
    /// from the data.
    pub fn default_start(self, kd: Rgb) -> Vec<f64> {
        let mut q = Vec::new();
        for d in self.params() {
            if d.colour {
                if matches!(d.name, "kd" | "albedo" | "rd") {
                    q.extend(kd.iter().map(|v| v.clamp(0.01, 0.95)));
                } else {
                    q.extend([d.start; 3]);
                }
            } else {
                q.push(d.start);
            }
        }
        q
    }

    /// The material spec (accepted by `brdf::spec::load`) of model parameters `q`.
    pub fn spec(self, q: &[f64]) -> String {
        if self == ModelKind::LafortuneRgb {
            // One single-channel lobe per colour channel of the multi-lobe Lafortune model.
            let mut parts = vec![format!("kd={}/{}/{}", q[0], q[1], q[2])];
            for c in 0..3 {
                let mut rho = [0.0; 3];
                rho[c] = q[9 + c];
                let k = c + 1;
                parts.push(format!(
                    "cx{k}={},cz{k}=1,n{k}={},rho{k}={}/{}/{}",
                    q[3 + c],
                    q[6 + c],
                    rho[0],
                    rho[1],
                    rho[2]
                ));
            }
            return format!("lafortune:{}", parts.join(","));
        }
        let mut parts = Vec::new();
        let mut k = 0;
        for d in self.params() {
            if d.colour {
                parts.push(format!("{}={}/{}/{}", d.name, q[k], q[k + 1], q[k + 2]));
                k += 3;
            } else {
                parts.push(format!("{}={}", d.name, q[k]));
                k += 1;
            }
        }
        let head = match self {
            ModelKind::Lambert => "lambert",
            ModelKind::OrenNayar => "oren-nayar",
            ModelKind::BlinnPhong => "blinn",
            ModelKind::Phong => "phong",
            ModelKind::Ward => "ward",
            ModelKind::LafortuneRgb => "lafortune",
            ModelKind::Lafortune1 | ModelKind::Lafortune2 => {
                // Lobes are written with cz = 1 (the fit's normalisation).
                parts.push("cz1=1".into());
                if self == ModelKind::Lafortune2 {
                    parts.push("cz2=1".into());
                }
                "lafortune"
            }
            ModelKind::CookTorrance => "ct",
            ModelKind::CookTorrance2 => "ct2",
            ModelKind::Ggx => "ggx",
            ModelKind::Ggx2 => "ggx2",
            ModelKind::AshikhminShirley => "as",
            ModelKind::Htsg => "htsg",
        };
        format!("{head}:{}", parts.join(","))
    }

    /// BRDF value for model parameters `q` at a precomputed direction pair.
    pub fn eval<T: Real>(self, q: &[T], g: &Geom) -> [T; 3] {
        let diffuse = |kd: &[T]| [kd[0] * FRAC_1_PI, kd[1] * FRAC_1_PI, kd[2] * FRAC_1_PI];
        let add = |mut a: [T; 3], ks: &[T], s: T| {
            for c in 0..3 {
                a[c] = a[c] + ks[c] * s;
            }
            a
        };
        match self {
            ModelKind::Lambert => diffuse(&q[0..3]),
            ModelKind::OrenNayar => {
                let s2 = q[3] * q[3];
                let a = -(s2 * 0.5 / (s2 + 0.33)) + 1.0;
                let b = s2 * 0.45 / (s2 + 0.09);
                let k = a + b * g.oren_nayar;
                let d = diffuse(&q[0..3]);
                [d[0] * k, d[1] * k, d[2] * k]
            }
            ModelKind::BlinnPhong => {
                let n = q[6];
                let s = (n + 8.0) / (8.0 * PI) * pow_pos(g.h_z, n);
                add(diffuse(&q[0..3]), &q[3..6], s)
            }
            ModelKind::Phong => {
                let n = q[6];
                let s = (n + 2.0) / (2.0 * PI) * pow_pos(g.mirror, n);
                add(diffuse(&q[0..3]), &q[3..6], s)
            }
            ModelKind::Ward => {
                let a2 = q[6] * q[6];
                let s = (-(T::cst(g.tan2_h) / a2)).exp() / (a2 * (4.0 * PI * g.sqrt_zz));
                add(diffuse(&q[0..3]), &q[3..6], s)
            }
            ModelKind::Lafortune1 | ModelKind::Lafortune2 => {
                let mut out = diffuse(&q[0..3]);
                let lobes = if self == ModelKind::Lafortune2 { 2 } else { 1 };
                for l in 0..lobes {
                    let o = 3 + 5 * l;
                    let base = q[o] * g.tangential + g.zz;
                    if base.val() > 0.0 {
                        let s = (q[o + 1] * base.ln()).exp();
                        out = add(out, &q[o + 2..o + 5], s);
                    }
                }
                out
            }
            ModelKind::LafortuneRgb => {
                let mut out = diffuse(&q[0..3]);
                for c in 0..3 {
                    let base = q[3 + c] * g.tangential + g.zz;
                    if base.val() > 0.0 {
                        out[c] = out[c] + q[9 + c] * (q[6 + c] * base.ln()).exp();
                    }
                }
                out
            }
            ModelKind::CookTorrance => {
                let s = beckmann_lobe(q[6], g) * fresnel(g.cos_d, q[7]);
                add(diffuse(&q[0..3]), &q[3..6], s)
            }
            ModelKind::CookTorrance2 => {
                let f = fresnel(g.cos_d, q[11]);
                let out = add(diffuse(&q[0..3]), &q[3..6], beckmann_lobe(q[6], g) * f);
                add(out, &q[7..10], beckmann_lobe(q[10], g) * f)
            }
            ModelKind::Ggx => {
                let s = ggx_lobe(q[6], g) * fresnel(g.cos_d, q[7]);
                add(diffuse(&q[0..3]), &q[3..6], s)
            }
            ModelKind::Ggx2 => {
                let f = fresnel(g.cos_d, q[11]);
                let out = add(diffuse(&q[0..3]), &q[3..6], ggx_lobe(q[6], g) * f);
                add(out, &q[7..10], ggx_lobe(q[10], g) * f)
            }
            ModelKind::AshikhminShirley => {
                let n = q[6];
                let spec = (n + 1.0) / (8.0 * PI) * pow_pos(g.h_z, n) * g.as_geometry;
                let mut out = [T::cst(0.0); 3];
                for c in 0..3 {
                    let (rd, rs) = (q[c], q[3 + c]);
                    let diffuse = rd * (-rs + 1.0) * (28.0 / (23.0 * PI) * g.as_diffuse);
                    let fres = rs + (-rs + 1.0) * g.schlick5;
                    out[c] = diffuse + spec * fres;
                }
                out
            }
            ModelKind::Htsg => {
                let lobe = htsg_lobes(q[6], q[7], q[8], g);
                let mut out = diffuse(&q[0..3]);
                for c in 0..3 {
                    out[c] = out[c] + q[3 + c] * lobe[c];
                }
                out
            }
        }
    }
}

/// The directional-diffuse term of the He-Torrance-Sillion-Greenberg model per colour channel,
/// the same formula as `brdf::analytic::Htsg::directional_diffuse`, generic for the gradients.
fn htsg_lobes<T: Real>(sigma0: T, tau: T, ior: T, g: &Geom) -> [T; 3] {
    use brdf::analytic::htsg::{effective_height, series_with_partials, SERIES_MAX_G};
    let sqrt_pi = PI.sqrt();
    let shadowing = |cot: f64| {
        if cot.is_infinite() {
            return T::cst(1.0);
        }
        let a = tau * (0.5 * cot) / sigma0;
        if a.val() <= 1e-12 {
            return T::cst(0.0);
        }
        let e = a.erfc();
        let lambda = ((-(a * a)).exp() / (a * sqrt_pi) - e) * 0.5;
        (-(e * 0.5) + 1.0) / (lambda + 1.0)
    };
    let k_term = |cot: f64| {
        if cot.is_infinite() {
            return T::cst(0.0);
        }
        (tau * (0.5 * cot) / sigma0).erfc() * (1.0 / cot.max(1e-300))
    };
    let s = shadowing(g.cot_i) * shadowing(g.cot_o);
    // z₀/σ₀ from the f64 root, then one Newton step in T: exact value, exact first derivatives.
    let c = (k_term(g.cot_i) + k_term(g.cot_o)) * 0.25;
    let u0 = effective_height(c.val());
    let e0 = (-0.5 * u0 * u0).exp();
    let k = (0.5 * PI).sqrt();
    let u = -((-(c * e0) + k * u0) / (c * (u0 * e0) + k)) + u0;
    let sigma = sigma0 / (u * u + 1.0).sqrt();
    let base = fresnel(g.cos_d, ior) * s * ((g.v2 / g.v_z).powi(2) / (PI * g.zz));
    let mut out = [T::cst(0.0); 3];
    for (c, lambda) in brdf::analytic::htsg::WAVELENGTHS_UM.iter().enumerate() {
        let gg = {
            let x = sigma * (2.0 * PI * g.v_z / lambda);
            x * x
        };
        let a = tau * tau * ((PI / lambda).powi(2) * g.v_xy2);
        let series = if gg.val() <= 0.0 {
            T::cst(0.0)
        } else if gg.val() > SERIES_MAX_G {
            let d1 = a / (gg * gg) - T::cst(1.0) / gg;
            let d2 = T::cst(1.0) / (gg * gg) - a * 2.0 / (gg * gg * gg);
            (-(a / gg)).exp() / gg * ((d1 * d1 + d2) * gg * 0.5 + 1.0)
        } else {
            // The sum and its two partial derivatives in f64, then lifted to T by the chain
            // rule: the terms themselves need no derivative arithmetic.
            let (g0, a0) = (gg.val(), a.val());
            let (sum, d_g, d_a) = series_with_partials(g0, a0);
            (gg - g0) * d_g + (a - a0) * d_a + sum
        };
        let d = tau * tau * ((PI / (2.0 * lambda)).powi(2)) * series;
        out[c] = base * d;
    }
    out
}

/// `x^n` for a constant `x ≥ 0` and a variable exponent.
#[inline]
fn pow_pos<T: Real>(x: f64, n: T) -> T {
    if x <= 0.0 {
        T::cst(0.0)
    } else {
        (n * x.ln()).exp()
    }
}

/// Beckmann D · G / (4 cos θi cos θo) with V-cavity G.
#[inline]
fn beckmann_lobe<T: Real>(m: T, g: &Geom) -> T {
    let m2 = m * m;
    let d = (-(T::cst(g.tan2_h) / m2)).exp() / (m2 * (PI * g.h_z4));
    d * (g.v_cavity / (4.0 * g.zz))
}

/// GGX D · G₂ / (4 cos θi cos θo) with Smith height-correlated G₂.
#[inline]
fn ggx_lobe<T: Real>(alpha: T, g: &Geom) -> T {
    let a2 = alpha * alpha;
    let t = (a2 - 1.0) * (g.h_z * g.h_z) + 1.0;
    let d = a2 / (t * t * PI);
    let lambda = |tan2: f64| ((a2 * tan2 + 1.0).sqrt() - 1.0) * 0.5;
    let g2 = T::cst(1.0) / (lambda(g.tan2_i) + lambda(g.tan2_o) + 1.0);
    d * g2 / (4.0 * g.zz)
}

/// Exact unpolarised dielectric Fresnel reflectance, variable index `eta` ≥ 1.
#[inline]
fn fresnel<T: Real>(cos_i: f64, eta: T) -> T {
    let c = cos_i.abs().min(1.0);
    let g2 = eta * eta + (c * c - 1.0);
    if g2.val() <= 0.0 {
        return T::cst(1.0);
    }
    let g = g2.sqrt();
    let a = (g - c) / (g + c);
    let b = ((g + c) * c - 1.0) / ((g - c) * c + 1.0);
    a * a * (b * b + 1.0) * 0.5
}

/// A direction pair with the geometric quantities the models need, computed once per bin.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Geom {
    /// cos θi · cos θo.
    pub zz: f64,
    /// √(cos θi cos θo).
    pub sqrt_zz: f64,
    /// ωi,x ωo,x + ωi,y ωo,y (the Lafortune tangential product).
    pub tangential: f64,
    /// cos of the angle between ωo and the mirror direction of ωi, clamped at 0.
    pub mirror: f64,
    /// cos θh.
    pub h_z: f64,
    /// cos⁴ θh.
    pub h_z4: f64,
    /// tan² θh.
    pub tan2_h: f64,
    /// tan² θi.
    pub tan2_i: f64,
    /// tan² θo.
    pub tan2_o: f64,
    /// ωi · h = cos θd.
    pub cos_d: f64,
    /// V-cavity shadowing-masking term.
    pub v_cavity: f64,
    /// cos Δφ · sin α · tan β of Oren-Nayar.
    pub oren_nayar: f64,
    /// Ashikhmin-Shirley's 1 / (ωi·h · max(cos θi, cos θo)).
    pub as_geometry: f64,
    /// Ashikhmin-Shirley's diffuse angular factor.
    pub as_diffuse: f64,
    /// (1 − ωi·h)⁵, Schlick's grazing factor.
    pub schlick5: f64,
    /// cot θi (infinite at normal incidence).
    pub cot_i: f64,
    /// cot θo.
    pub cot_o: f64,
    /// z component of ωi + ωo.
    pub v_z: f64,
    /// Squared tangential length of ωi + ωo.
    pub v_xy2: f64,
    /// |ωi + ωo|².
    pub v2: f64,
}

impl Geom {
    /// Geometry of a pair of unit directions, `None` when either is at or below the horizon.
    pub fn new(wi: &Vec3, wo: &Vec3) -> Option<Geom> {
        if wi.z <= 1e-9 || wo.z <= 1e-9 {
            return None;
        }
        let s = wi + wo;
        let h = if s.norm() > 0.0 {
            s / s.norm()
        } else {
            Vec3::z()
        };
        let hz = h.z.max(1e-12);
        let (zi, zo) = (wi.z, wo.z);
        let cos_d = wi.dot(&h).clamp(1e-12, 1.0);
        let oh = wo.dot(&h).max(1e-12);
        let tan2 = |z: f64| ((1.0 - z * z) / (z * z)).max(0.0);
        let cot = |z: f64| {
            let sin = (1.0 - z * z).max(0.0).sqrt();
            if sin > 0.0 {
                z / sin
            } else {
                f64::INFINITY
            }
        };
        let (ti, to) = (zi.clamp(-1.0, 1.0).acos(), zo.clamp(-1.0, 1.0).acos());
        let (alpha, beta) = (ti.max(to), ti.min(to));
        let pi_ = (wi.x * wi.x + wi.y * wi.y).sqrt();
        let po = (wo.x * wo.x + wo.y * wo.y).sqrt();
        let cos_dphi = if pi_ > 1e-12 && po > 1e-12 {
            ((wi.x * wo.x + wi.y * wo.y) / (pi_ * po)).max(0.0)
        } else {
            0.0
        };
        let r = Vec3::new(-wi.x, -wi.y, wi.z);
        Some(Geom {
            zz: zi * zo,
            sqrt_zz: (zi * zo).sqrt(),
            tangential: wi.x * wo.x + wi.y * wo.y,
            mirror: r.dot(wo).max(0.0),
            h_z: hz,
            h_z4: hz.powi(4),
            tan2_h: tan2(hz),
            tan2_i: tan2(zi),
            tan2_o: tan2(zo),
            cos_d,
            v_cavity: (2.0 * hz * zo / oh).min(2.0 * hz * zi / oh).min(1.0),
            oren_nayar: cos_dphi * alpha.sin() * beta.tan(),
            as_geometry: 1.0 / (cos_d * zi.max(zo)),
            as_diffuse: (1.0 - (1.0 - zi / 2.0).powi(5)) * (1.0 - (1.0 - zo / 2.0).powi(5)),
            schlick5: (1.0 - cos_d).powi(5),
            cot_i: cot(zi),
            cot_o: cot(zo),
            v_z: s.z,
            v_xy2: s.x * s.x + s.y * s.y,
            v2: s.norm_squared(),
        })
    }
}

/// A model with fitted parameters, usable directly as a [`Brdf`].
#[derive(Debug, Clone, PartialEq)]
pub struct Parametric {
    /// The model.
    pub kind: ModelKind,
    /// Model parameters (bounded, in the layout of [`ModelKind::params`]).
    pub q: Vec<f64>,
}

impl Parametric {
    /// The material spec string of the model.
    pub fn spec(&self) -> String {
        self.kind.spec(&self.q)
    }

    /// Named parameters, colours as three entries `name.r`, `name.g`, `name.b`.
    pub fn named(&self) -> Vec<(String, f64)> {
        let mut out = Vec::new();
        let mut k = 0;
        for d in self.kind.params() {
            if d.colour {
                for ch in ["r", "g", "b"] {
                    out.push((format!("{}.{ch}", d.name), self.q[k]));
                    k += 1;
                }
            } else {
                out.push((d.name.to_string(), self.q[k]));
                k += 1;
            }
        }
        out
    }
}

impl Brdf for Parametric {
    fn eval(&self, wi: &Vec3, wo: &Vec3) -> Rgb {
        match Geom::new(wi, wo) {
            Some(g) => self.kind.eval(&self.q, &g),
            None => [0.0; 3],
        }
    }
    fn name(&self) -> String {
        self.kind.name().into()
    }
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;
    use brdf::Spherical;
    use rand::{Rng, SeedableRng};

    /// A non-trivial parameter vector inside the bounds of every model.
    pub fn example_params(kind: ModelKind) -> Vec<f64> {
        let mut q = Vec::new();
        for (i, d) in kind.params().iter().enumerate() {
            if d.name == "cx" {
                q.extend([-1.1, -0.9, -1.0]);
            } else if d.name == "n" && d.colour {
                q.extend([80.0, 40.0, 20.0]);
            } else if d.colour {
                let base = if d.name.starts_with("rho") { 3.0 } else { 0.3 };
                q.extend([base * 0.8, base * 0.5, base * 0.3 + 0.01 * i as f64]);
            } else {
                q.push(match d.name {
                    "sigma" => 0.4,
                    "n" | "n1" => 80.0,
                    "n2" => 6.0,
                    "cx1" => -1.1,
                    "cx2" => -0.6,
                    "ior" => 1.7,
                    "tau" => 3.0,
                    "alpha1" | "m1" => 0.06,
                    _ => 0.25,
                });
            }
        }
        q
    }

    #[test]
    fn every_model_agrees_with_the_brdf_built_from_its_spec() {
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(5);
        for kind in ModelKind::ALL {
            let q = example_params(kind);
            assert_eq!(q.len(), kind.dimension());
            let p = Parametric { kind, q };
            let spec = p.spec();
            let loaded = brdf::spec::load(&spec).unwrap_or_else(|e| panic!("{spec}: {e}"));
            for _ in 0..2000 {
                let wi = Spherical::new(
                    rng.gen_range(0.0..1.5),
                    rng.gen_range(0.0..std::f64::consts::TAU),
                )
                .to_vector();
                let wo = Spherical::new(
                    rng.gen_range(0.0..1.5),
                    rng.gen_range(0.0..std::f64::consts::TAU),
                )
                .to_vector();
                let a = p.eval(&wi, &wo);
                let b = loaded.eval(&wi, &wo);
                for c in 0..3 {
                    assert!(
                        (a[c] - b[c]).abs() <= 1e-9 * b[c].abs().max(1e-3),
                        "{spec}: {a:?} vs {b:?}"
                    );
                }
            }
        }
    }

    #[test]
    fn bounds_round_trip() {
        for kind in ModelKind::ALL {
            let q = example_params(kind);
            let p = kind.to_solver(&q);
            let back = kind.to_model(&p);
            for (a, b) in q.iter().zip(&back) {
                assert!((a - b).abs() < 1e-9 * a.abs().max(1.0), "{kind:?} {a} {b}");
            }
        }
    }
}
