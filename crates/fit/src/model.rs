//! The fittable models: parameter layout, bounds, start points, model and spec.

use crate::dual::Real;
use crate::error::{FitError, Result};
use brdf::analytic::{self as an, Analytic, Pair, PairGeometry};
use brdf::{Brdf, Rgb, Vec3};
use std::f64::consts::FRAC_PI_2;

pub use brdf::analytic::Geom;

/// A fittable analytic model: its parameter layout, bounds, start points, the `brdf::analytic`
/// model of a parameter vector and its material spec.
///
/// Colour is per channel for the albedo-like parameters (diffuse, specular, lobe albedo); the
/// shape parameters (roughness, exponent, index of refraction, lobe direction) are shared by the
/// three channels, as a renderer uses them. The fitter evaluates `brdf`'s own models
/// ([`ModelKind::model`]), on dual numbers for the gradients; the tests check that the model of a
/// parameter vector is the one its spec string builds.
///
/// # Examples
///
/// ```
/// use fit::ModelKind;
/// use brdf::{Brdf, Vec3};
/// let kind = ModelKind::parse("ggx", 2).unwrap();
/// assert_eq!(kind, ModelKind::Ggx2);
/// assert_eq!(ModelKind::parse(kind.name(), 1).unwrap(), kind);
/// // The solver works in unbounded variables; the bounds come back on the round trip.
/// let q = kind.default_start([0.2, 0.3, 0.4]);
/// assert_eq!(q.len(), kind.dimension());
/// let back = kind.to_model(&kind.to_solver(&q));
/// assert!(q.iter().zip(&back).all(|(a, b)| (a - b).abs() < 1e-9));
/// // The spec string of a parameter vector builds the same material as the fitter's model.
/// let q = vec![0.2, 0.2, 0.2, 0.1, 0.1, 0.1, 0.15]; // kd, ks, alpha
/// let from_spec = brdf::load(&ModelKind::Ward.spec(&q)).unwrap();
/// let fitted = fit::Parametric { kind: ModelKind::Ward, q };
/// let wi = Vec3::new(0.3, 0.1, 0.95).normalize();
/// let wo = Vec3::new(-0.2, 0.0, 0.98).normalize();
/// let (a, b) = (from_spec.eval(&wi, &wo), fitted.eval(&wi, &wo));
/// assert!((0..3).all(|c| (a[c] - b[c]).abs() <= 1e-9 * a[c].abs().max(1.0)));
/// ```
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

    /// The material spec (accepted by `brdf::load`) of model parameters `q`.
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

    /// The `brdf::analytic` model of model parameters `q` (over `f64` for values, over
    /// [`crate::dual::Dual`] numbers for gradients). It is the model [`ModelKind::spec`] names.
    pub fn model<T: Real>(self, q: &[T]) -> Model<T> {
        let rgb = |k: usize| [q[k], q[k + 1], q[k + 2]];
        let one = T::cst(1.0);
        // An isotropic Lafortune lobe, Cz = 1 (the fit's normalisation).
        let lobe = |cx: T, exponent: T, rho: [T; 3]| an::LafortuneLobe {
            cx,
            cy: cx,
            cz: one,
            exponent,
            rho,
        };
        match self {
            ModelKind::Lambert => Model::Lambert(an::Lambert { kd: rgb(0) }),
            ModelKind::OrenNayar => Model::OrenNayar(an::OrenNayar {
                albedo: rgb(0),
                sigma: q[3],
            }),
            ModelKind::BlinnPhong => Model::BlinnPhong(an::BlinnPhong {
                kd: rgb(0),
                ks: rgb(3),
                exponent: q[6],
            }),
            ModelKind::Phong => Model::Phong(an::Phong {
                kd: rgb(0),
                ks: rgb(3),
                exponent: q[6],
            }),
            ModelKind::Ward => Model::Ward(an::Ward {
                kd: rgb(0),
                ks: rgb(3),
                alpha_x: q[6],
                alpha_y: q[6],
            }),
            ModelKind::Lafortune1 | ModelKind::Lafortune2 => {
                let lobes = if self == ModelKind::Lafortune2 { 2 } else { 1 };
                Model::Lafortune(an::Lafortune {
                    kd: rgb(0),
                    lobes: (0..lobes)
                        .map(|l| lobe(q[3 + 5 * l], q[4 + 5 * l], rgb(5 + 5 * l)))
                        .collect(),
                })
            }
            ModelKind::LafortuneRgb => Model::Lafortune(an::Lafortune {
                kd: rgb(0),
                // One lobe per colour channel, dark in the other two.
                lobes: (0..3)
                    .map(|c| {
                        let mut rho = [T::cst(0.0); 3];
                        rho[c] = q[9 + c];
                        lobe(q[3 + c], q[6 + c], rho)
                    })
                    .collect(),
            }),
            ModelKind::CookTorrance => Model::CookTorrance(an::CookTorrance {
                kd: rgb(0),
                ks: rgb(3),
                m: q[6],
                ior: q[7],
            }),
            ModelKind::CookTorrance2 => Model::CookTorrance2(an::CookTorranceTwoLobe {
                kd: rgb(0),
                ks: [rgb(3), rgb(7)],
                m: [q[6], q[10]],
                ior: q[11],
            }),
            ModelKind::Ggx => Model::Ggx(an::Ggx {
                kd: rgb(0),
                ks: rgb(3),
                alpha: q[6],
                ior: q[7],
            }),
            ModelKind::Ggx2 => Model::Ggx2(an::GgxTwoLobe {
                kd: rgb(0),
                ks: [rgb(3), rgb(7)],
                alpha: [q[6], q[10]],
                ior: q[11],
            }),
            ModelKind::AshikhminShirley => Model::AshikhminShirley(an::AshikhminShirley {
                rd: rgb(0),
                rs: rgb(3),
                nu: q[6],
                nv: q[6],
            }),
            ModelKind::Htsg => Model::Htsg(an::Htsg {
                kd: rgb(0),
                ks: rgb(3),
                sigma: q[6],
                tau: q[7],
                ior: q[8],
            }),
        }
    }
}

/// The `brdf::analytic` model of a [`ModelKind`] and its parameters ([`ModelKind::model`]),
/// over the scalar `T`; evaluated by `brdf`'s code through [`Analytic::value`].
#[derive(Debug, Clone, PartialEq)]
pub enum Model<T: Real> {
    /// [`ModelKind::Lambert`].
    Lambert(an::Lambert<T>),
    /// [`ModelKind::OrenNayar`].
    OrenNayar(an::OrenNayar<T>),
    /// [`ModelKind::BlinnPhong`].
    BlinnPhong(an::BlinnPhong<T>),
    /// [`ModelKind::Phong`].
    Phong(an::Phong<T>),
    /// [`ModelKind::Ward`] (αx = αy).
    Ward(an::Ward<T>),
    /// [`ModelKind::Lafortune1`], [`ModelKind::Lafortune2`] and [`ModelKind::LafortuneRgb`]
    /// (isotropic lobes, Cz = 1; one lobe per channel for the last).
    Lafortune(an::Lafortune<T>),
    /// [`ModelKind::CookTorrance`].
    CookTorrance(an::CookTorrance<T>),
    /// [`ModelKind::CookTorrance2`].
    CookTorrance2(an::CookTorranceTwoLobe<T>),
    /// [`ModelKind::Ggx`].
    Ggx(an::Ggx<T>),
    /// [`ModelKind::Ggx2`].
    Ggx2(an::GgxTwoLobe<T>),
    /// [`ModelKind::AshikhminShirley`] (nu = nv).
    AshikhminShirley(an::AshikhminShirley<T>),
    /// [`ModelKind::Htsg`].
    Htsg(an::Htsg<T>),
}

impl<T: Real> Analytic<T> for Model<T> {
    #[inline]
    fn value<G: PairGeometry>(&self, g: &G) -> [T; 3] {
        match self {
            Model::Lambert(m) => m.value(g),
            Model::OrenNayar(m) => m.value(g),
            Model::BlinnPhong(m) => m.value(g),
            Model::Phong(m) => m.value(g),
            Model::Ward(m) => m.value(g),
            Model::Lafortune(m) => m.value(g),
            Model::CookTorrance(m) => m.value(g),
            Model::CookTorrance2(m) => m.value(g),
            Model::Ggx(m) => m.value(g),
            Model::Ggx2(m) => m.value(g),
            Model::AshikhminShirley(m) => m.value(g),
            Model::Htsg(m) => m.value(g),
        }
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
        // Zero where [`Geom::new`] has no geometry, as in the fit.
        if wi.z <= 1e-9 || wo.z <= 1e-9 {
            return [0.0; 3];
        }
        self.kind.model(&self.q).value(&Pair::new(wi, wo))
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
            let loaded = brdf::load(&spec).unwrap_or_else(|e| panic!("{spec}: {e}"));
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

    /// Random direction pairs above the horizon, as cached geometry.
    fn random_geoms(rng: &mut impl Rng, n: usize) -> Vec<Geom> {
        let mut dir = || {
            Spherical::new(
                rng.gen_range(0.0..1.5),
                rng.gen_range(0.0..std::f64::consts::TAU),
            )
            .to_vector()
        };
        (0..n).filter_map(|_| Geom::new(&dir(), &dir())).collect()
    }

    #[test]
    fn dual_gradients_equal_central_differences_of_the_values() {
        use crate::dual::Dual;
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(17);
        let geoms = random_geoms(&mut rng, 300);
        for kind in ModelKind::ALL {
            let start = kind.to_solver(&example_params(kind));
            for _ in 0..3 {
                // A parameter point near the example, inside the bounds.
                let p: Vec<f64> = start.iter().map(|v| v + rng.gen_range(-0.5..0.5)).collect();
                let q = kind.to_model(&p);
                let qd: Vec<Dual<16>> = q
                    .iter()
                    .enumerate()
                    .map(|(i, v)| Dual::var(*v, i))
                    .collect();
                let dual = kind.model(&qd);
                for g in &geoms {
                    let f = dual.value(g);
                    for i in 0..q.len() {
                        let h = 1e-6 * q[i].abs().max(1e-2);
                        let (mut up, mut down) = (q.clone(), q.clone());
                        up[i] += h;
                        down[i] -= h;
                        let (fu, fdn) = (kind.model(&up).value(g), kind.model(&down).value(g));
                        for c in 0..3 {
                            let fd = (fu[c] - fdn[c]) / (2.0 * h);
                            let d = f[c].d[i];
                            let tol = 1e-5 * (d.abs() + fd.abs()) + 1e-9 * f[c].v.abs() / h;
                            assert!(
                                (d - fd).abs() <= tol,
                                "{kind:?} q {q:?}: ∂f{c}/∂q{i} {d} vs {fd} (value {})",
                                f[c].v
                            );
                        }
                    }
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
