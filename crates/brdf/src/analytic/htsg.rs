//! The He-Torrance-Sillion-Greenberg model (thesis §2.2.2), isotropic, for unpolarised light.
//!
//! A surface of Gaussian random heights with rms roughness σ₀ and autocorrelation length τ
//! (both in micrometres) reflects in three parts: a coherent mirror spike, a directional-diffuse
//! lobe from diffraction by the roughness, and a uniform-diffuse part from multiple and
//! subsurface scattering. This implementation evaluates
//!
//! f = kd/π + ks · F(ωi·h) G S D / (π cos θi cos θo)
//!
//! per colour channel at a wavelength λ of [`WAVELENGTHS_UM`]:
//!
//! * `D = (πτ/2λ)² Σₘ₌₁^∞ gᵐ e⁻ᵍ / (m! m) · exp(−(πτ/λ)² v²ₓᵧ / m)`, the diffraction series, with
//!   `g = (2πσ v_z / λ)²` and `v = ωi + ωo` (the scattering vector over k = 2π/λ);
//! * `σ = σ₀ / √(1 + z₀²/σ₀²)` the effective roughness, `z₀` solving
//!   `√(π/2) z₀ = σ₀/4 (Kᵢ + Kₒ) exp(−z₀²/2σ₀²)` with `K = tan θ · erfc(τ cot θ / 2σ₀)`;
//! * `S = S(θi) S(θo)`, `S(θ) = (1 − ½ erfc(a)) / (Λ(a) + 1)`, `a = τ cot θ / 2σ₀`,
//!   `Λ(a) = ½ (e^{−a²}/(a√π) − erfc(a))` (Smith shadowing of the Gaussian surface);
//! * `G = (|v|² / v_z)²`, the geometrical factor of the original model for unpolarised light
//!   (its polarisation brackets reduce to |k̂ᵣ × k̂ᵢ|² each);
//! * F the exact dielectric Fresnel reflectance of relative index `ior`.
//!
//! `ks` = 1 is the physical model; the colour scale lets a fit absorb the reflectance of metals
//! and coatings that a real index does not describe, as the other microfacet models here do.
//! The coherent mirror spike `|F|² e⁻ᵍ S` is a Dirac delta in the mirror direction; a pointwise
//! BRDF cannot hold it, so it is left out. Its weight e⁻ᵍ falls fast with roughness: at normal
//! incidence in green light it is 0.5 % for σ₀ = 0.1 µm but 81 % for σ₀ = 0.02 µm, so for
//! very smooth surfaces the model keeps only the directional-diffuse part of their reflection.
//!
//! For g above [`SERIES_MAX_G`] the series is replaced by its second-order expansion around the
//! Poisson mean (relative error O(g⁻²)), which is also the geometric-optics limit: there the
//! lobe becomes the Beckmann microfacet lobe of rms slope 2σ/τ (a test checks it).

use super::geometry::cot;
use super::{
    analytic_brdf, below, check_param, check_rgb, diffuse, fresnel_dielectric, Analytic, Pair,
    PairGeometry,
};
use crate::coords::Vec3;
use crate::error::Result;
use crate::real::Real;
use crate::{Brdf, Rgb};
use std::f64::consts::PI;
use std::sync::OnceLock;

/// Wavelengths (µm) at which the red, green and blue channels are evaluated.
pub const WAVELENGTHS_UM: [f64; 3] = [0.65, 0.55, 0.45];

/// Above this value of g the diffraction series is replaced by its asymptotic expansion.
pub const SERIES_MAX_G: f64 = 400.0;

/// Largest m for which ln m! is tabulated: enough for the series window at [`SERIES_MAX_G`].
const MAX_TERMS: usize = 1024;

/// ln m! for m ≤ 1024 (tabulated once).
pub fn ln_factorial(m: usize) -> f64 {
    static TABLE: OnceLock<Vec<f64>> = OnceLock::new();
    let t = TABLE.get_or_init(|| {
        let mut t = Vec::with_capacity(MAX_TERMS + 1);
        let mut acc = 0.0;
        t.push(0.0);
        for k in 1..=MAX_TERMS {
            acc += (k as f64).ln();
            t.push(acc);
        }
        t
    });
    t[m.min(MAX_TERMS)]
}

/// Relative size below which the remaining terms of the series are dropped.
const SERIES_TOLERANCE: f64 = 1e-12;

/// Σₘ₌₁^∞ gᵐ e⁻ᵍ / (m! m) · e^{−a/m}: exact summation up to [`SERIES_MAX_G`], its expansion
/// beyond (0 where g ≤ 0).
///
/// Below [`SERIES_MAX_G`] the sum and its two partial derivatives are computed in `f64` and lifted
/// to `T` by the chain rule: the terms themselves need no derivative arithmetic.
pub fn diffraction_series<T: Real>(g: T, a: T) -> T {
    let (g0, a0) = (g.val(), a.val());
    if g0 > SERIES_MAX_G {
        return series_expansion(g, a);
    }
    if g0 <= 0.0 || g0.is_nan() {
        return T::cst(0.0);
    }
    let (sum, d_g, d_a) = series_with_partials(g0, a0);
    (g - g0) * d_g + (a - a0) * d_a + sum
}

/// The exact sum S(g, a) = Σₘ₌₁^∞ gᵐ e⁻ᵍ / (m! m) · e^{−a/m} (for 0 ≤ g ≤ [`SERIES_MAX_G`], a ≥ 0)
/// with its partial derivatives (S, ∂S/∂g, ∂S/∂a).
///
/// The Poisson weights gᵐe⁻ᵍ/m! are negligible more than six standard deviations below their
/// peak at m ≈ g, where the sum starts; they are updated by the ratio g/m, and the summation
/// stops once the terms decrease and fall below 10⁻¹² of the running sum (for large a the
/// factor e^{−a/m} moves the mass of the series above m = g, so the end is found, not fixed).
pub fn series_with_partials(g: f64, a: f64) -> (f64, f64, f64) {
    if g <= 0.0 || g.is_nan() || a.is_nan() {
        return (0.0, 0.0, 0.0);
    }
    let lo = (g - 6.0 * g.sqrt() - 5.0).floor().max(1.0) as usize;
    let lo_f = lo as f64;
    // Poisson weight at m = lo.
    let mut p = (lo_f * g.ln() - g - ln_factorial(lo)).exp();
    // e^{−a/m}, carried from term to term by its ratio e^{a/(m(m+1))} (see below)
    let mut damping = (-a / lo_f).exp();
    // Σ t, Σ t·m and Σ t/m give the sum and both partial derivatives:
    // ∂/∂g of gᵐe⁻ᵍ is (m/g − 1)·gᵐe⁻ᵍ, ∂/∂a of e^{−a/m} is −e^{−a/m}/m.
    let (mut sum, mut sum_m, mut sum_inv) = (0.0, 0.0, 0.0);
    let mut previous = 0.0;
    let mut inv_m = 1.0 / lo_f;
    for m in lo..=MAX_TERMS {
        let mf = m as f64;
        let t = p * damping * inv_m;
        sum += t;
        sum_m += t * mf;
        sum_inv += t * inv_m;
        if mf > g && t <= previous && t <= SERIES_TOLERANCE * sum {
            break;
        }
        previous = t;
        let inv_next = 1.0 / (mf + 1.0);
        p *= g * inv_next;
        damping = next_damping(damping, a, inv_m, inv_next, mf + 1.0);
        inv_m = inv_next;
    }
    (sum, sum_m / g - sum, -sum_inv)
}

/// e^{−a/(m+1)} from e^{−a/m} (`damping`): times e^δ with δ = a/(m(m+1)), by its Taylor
/// polynomial while δ < 10⁻² (remainder below 2·10⁻¹⁵ relative), which saves an `exp` per
/// term of the series; an exact `exp` where δ is larger or the running value has underflowed.
#[inline]
fn next_damping(damping: f64, a: f64, inv_m: f64, inv_next: f64, next: f64) -> f64 {
    let delta = a * inv_m * inv_next;
    if delta < 1e-2 && damping > 1e-200 {
        let growth = 1.0
            + delta
                * (1.0
                    + delta * (0.5 + delta * (1.0 / 6.0 + delta * (1.0 / 24.0 + delta / 120.0))));
        damping * growth
    } else {
        (-a / next).exp()
    }
}

/// The second-order expansion of the series around m = g: φ(g) (1 + g φ''(g) / 2φ(g)) with
/// φ(m) = e^{−a/m}/m.
pub fn series_expansion<T: Real>(g: T, a: T) -> T {
    let d1 = a / (g * g) - T::cst(1.0) / g;
    let d2 = T::cst(1.0) / (g * g) - a * 2.0 / (g * g * g);
    (-(a / g)).exp() / g * ((d1 * d1 + d2) * g * 0.5 + 1.0)
}

/// Smith shadowing of one direction (cosine `cos_t`) over the Gaussian surface.
pub fn shadowing<T: Real>(cos_t: f64, sigma0: T, tau: T) -> T {
    shadowing_of_cot(cot(cos_t), sigma0, tau)
}

/// [`shadowing`] of a direction with cotangent `cot` (infinite at the normal).
pub fn shadowing_of_cot<T: Real>(cot: f64, sigma0: T, tau: T) -> T {
    if cot.is_infinite() {
        return T::cst(1.0);
    }
    let a = tau * (0.5 * cot) / sigma0;
    if a.val() <= 1e-12 {
        return T::cst(0.0);
    }
    let e = a.erfc();
    let lambda = ((-(a * a)).exp() / (a * PI.sqrt()) - e) * 0.5;
    (-(e * 0.5) + 1.0) / (lambda + 1.0)
}

/// `K(θ) = tan θ · erfc(τ cot θ / 2σ₀)` of the effective-roughness equation.
pub fn shadow_k<T: Real>(cos_t: f64, sigma0: T, tau: T) -> T {
    shadow_k_of_cot(cot(cos_t), sigma0, tau)
}

/// [`shadow_k`] of a direction with cotangent `cot` (infinite at the normal).
pub fn shadow_k_of_cot<T: Real>(cot: f64, sigma0: T, tau: T) -> T {
    if cot.is_infinite() {
        return T::cst(0.0);
    }
    (tau * (0.5 * cot) / sigma0).erfc() * (1.0 / cot.max(1e-300))
}

/// The root u = z₀/σ₀ ≥ 0 of √(π/2) u = c e^{−u²/2} (c ≥ 0), by safeguarded Newton iteration.
pub fn effective_height(c: f64) -> f64 {
    if c <= 0.0 {
        return 0.0;
    }
    let k = (0.5 * PI).sqrt();
    let (mut lo, mut hi) = (0.0, c / k);
    let mut u = 0.5 * hi;
    for _ in 0..60 {
        let e = (-0.5 * u * u).exp();
        let h = k * u - c * e;
        if h > 0.0 {
            hi = u;
        } else {
            lo = u;
        }
        let step = h / (k + c * u * e);
        let mut next = u - step;
        if !(next > lo && next < hi) {
            next = 0.5 * (lo + hi);
        }
        if (next - u).abs() <= 1e-14 * u.max(1e-300) {
            return next;
        }
        u = next;
    }
    u
}

/// The He-Torrance-Sillion-Greenberg model (module documentation above).
#[derive(Debug, Clone, PartialEq)]
pub struct Htsg<T: Real = f64> {
    /// Uniform-diffuse albedo.
    pub kd: [T; 3],
    /// Scale of the directional-diffuse lobe (1 = the physical model).
    pub ks: [T; 3],
    /// rms surface roughness σ₀ (µm).
    pub sigma: T,
    /// Autocorrelation length τ (µm).
    pub tau: T,
    /// Relative index of refraction.
    pub ior: T,
}

impl Htsg {
    /// Checks the parameters.
    pub fn validate(&self) -> Result<()> {
        check_rgb("htsg", "kd", &self.kd, 0.0, 1.0)?;
        check_rgb("htsg", "ks", &self.ks, 0.0, 100.0)?;
        check_param("htsg", "sigma", self.sigma, 1e-4, 10.0)?;
        check_param("htsg", "tau", self.tau, 1e-3, 100.0)?;
        check_param("htsg", "ior", self.ior, 1.0, 100.0)
    }

    /// The directional-diffuse term F G S D / (π cos θi cos θo) at wavelength `lambda` (µm).
    pub fn directional_diffuse(&self, wi: &Vec3, wo: &Vec3, lambda: f64) -> f64 {
        if below(wi, wo) {
            return 0.0;
        }
        let g = Pair::new(wi, wo);
        let (base, sigma) = self.lobe_base(&g);
        base * self.diffraction(sigma, &g, lambda)
    }
}

impl<T: Real> Htsg<T> {
    /// The wavelength-independent part of the directional-diffuse term, F G S / (π cos θi cos θo),
    /// and the effective roughness σ.
    fn lobe_base<G: PairGeometry>(&self, g: &G) -> (T, T) {
        let (sigma0, tau) = (self.sigma, self.tau);
        let s = shadowing_of_cot(g.cot_i(), sigma0, tau) * shadowing_of_cot(g.cot_o(), sigma0, tau);
        // z₀/σ₀ from the f64 root, then one Newton step in T: exact value, exact first derivatives.
        let c = (shadow_k_of_cot(g.cot_i(), sigma0, tau) + shadow_k_of_cot(g.cot_o(), sigma0, tau))
            * 0.25;
        let u0 = effective_height(c.val());
        let e0 = (-0.5 * u0 * u0).exp();
        let k = (0.5 * PI).sqrt();
        let u = -((-(c * e0) + k * u0) / (c * (u0 * e0) + k)) + u0;
        let sigma = sigma0 / (u * u + 1.0).sqrt();
        let geometry = (g.v2() / g.v_z()).powi(2) / (PI * g.zz());
        (
            fresnel_dielectric(g.cos_d(), self.ior) * s * geometry,
            sigma,
        )
    }

    /// The diffraction factor D at wavelength `lambda` for the effective roughness `sigma`.
    fn diffraction<G: PairGeometry>(&self, sigma: T, g: &G, lambda: f64) -> T {
        let x = sigma * (2.0 * PI * g.v_z() / lambda);
        let tau2 = self.tau * self.tau;
        let a = tau2 * ((PI / lambda).powi(2) * g.v_xy2());
        tau2 * (PI / (2.0 * lambda)).powi(2) * diffraction_series(x * x, a)
    }
}

impl<T: Real> Analytic<T> for Htsg<T> {
    fn value<G: PairGeometry>(&self, g: &G) -> [T; 3] {
        let (base, sigma) = self.lobe_base(g);
        let mut out = diffuse(&self.kd);
        for (c, lambda) in WAVELENGTHS_UM.iter().enumerate() {
            out[c] = out[c] + self.ks[c] * (base * self.diffraction(sigma, g, *lambda));
        }
        out
    }
}

analytic_brdf!(Htsg, "htsg");

#[cfg(test)]
mod tests {
    use super::*;
    use crate::coords::Spherical;
    use crate::summary::directional_albedo;

    #[test]
    fn series_expansion_meets_the_exact_sum_where_they_switch() {
        for g in [150.0, 300.0, SERIES_MAX_G] {
            for a in [0.0, 0.3 * g, g, 4.0 * g] {
                let exact = diffraction_series(g, a);
                let approx = series_expansion(g, a);
                let rel = (exact - approx).abs() / exact;
                assert!(rel < 2e-3, "g {g} a {a}: {exact} vs {approx} ({rel})");
            }
        }
    }

    #[test]
    fn windowed_series_and_its_partials_match_the_full_sum() {
        // Every term from m = 1 to 1024 in log space, against the windowed recurrence.
        let full = |g: f64, a: f64| -> f64 {
            (1..=MAX_TERMS)
                .map(|m| {
                    let mf = m as f64;
                    (mf * g.ln() - g - ln_factorial(m) - mf.ln() - a / mf).exp()
                })
                .sum()
        };
        for g in [1e-3, 0.5, 3.0, 40.0, 250.0, SERIES_MAX_G] {
            for a in [0.0, 0.2 * g, 5.0 * g, 40.0 * g] {
                let (s, d_g, d_a) = series_with_partials(g, a);
                let reference = full(g, a);
                assert!(
                    (s - reference).abs() <= 1e-10 * reference,
                    "g {g} a {a}: {s} vs {reference}"
                );
                let h = 1e-5 * g.max(1e-3);
                let fd_g = (full(g + h, a) - full(g - h, a)) / (2.0 * h);
                let ha = 1e-5 * a.max(1.0);
                let fd_a =
                    (full(g, a + ha) - full(g, (a - ha).max(0.0))) / (a + ha - (a - ha).max(0.0));
                let scale = reference.abs().max(1e-300);
                assert!(
                    (d_g - fd_g).abs() <= 1e-5 * scale / g.min(1.0),
                    "dS/dg g {g} a {a}: {d_g} vs {fd_g}"
                );
                assert!(
                    (d_a - fd_a).abs() <= 1e-5 * scale,
                    "dS/da g {g} a {a}: {d_a} vs {fd_a}"
                );
            }
        }
    }

    #[test]
    fn series_of_a_smooth_surface_is_its_first_term() {
        // g ≪ 1: Σ ≈ g e^{-g} e^{-a}.
        let (g, a) = (1e-4, 0.7);
        let s = diffraction_series(g, a);
        let first = g * (-g).exp() * (-a).exp();
        assert!((s - first).abs() < 1e-4 * first, "{s} {first}");
    }

    #[test]
    fn effective_height_solves_its_equation() {
        for c in [1e-6, 0.01, 0.3, 1.0, 10.0, 1e3] {
            let u = effective_height(c);
            let h = (0.5 * PI).sqrt() * u - c * (-0.5 * u * u).exp();
            assert!(h.abs() < 1e-10 * c.max(1.0), "c {c}: u {u}, residual {h}");
        }
    }

    /// In the geometric-optics limit (g ≫ 1) the lobe is the Beckmann microfacet lobe
    /// F D S / (4 cos θi cos θo) with rms slope m = 2σ/τ, computed here independently.
    #[test]
    fn rough_surfaces_reflect_as_beckmann_microfacets() {
        let model = Htsg {
            kd: [0.0; 3],
            ks: [1.0; 3],
            sigma: 3.0,
            tau: 30.0,
            ior: 1.5,
        };
        let m = 2.0 * model.sigma / model.tau;
        for (ti, to, dphi) in [
            (0.2, 0.25, 3.0),
            (0.3, 0.1, 3.1),
            (0.05, 0.4, 2.9),
            (0.5, 0.45, 3.1),
        ] {
            let wi = Spherical::new(ti, 0.0).to_vector();
            let wo = Spherical::new(to, dphi).to_vector();
            let h = (wi + wo).normalize();
            let tan2 = (1.0 - h.z * h.z) / (h.z * h.z);
            let d = (-tan2 / (m * m)).exp() / (PI * m * m * h.z.powi(4));
            let s =
                shadowing(wi.z, model.sigma, model.tau) * shadowing(wo.z, model.sigma, model.tau);
            let expected = fresnel_dielectric(wi.dot(&h), model.ior) * d * s / (4.0 * wi.z * wo.z);
            let got = model.directional_diffuse(&wi, &wo, 0.55);
            let rel = (got - expected).abs() / expected;
            assert!(
                rel < 0.03,
                "({ti}, {to}, {dphi}): {got} vs {expected} ({rel})"
            );
        }
    }

    #[test]
    fn the_physical_model_conserves_energy() {
        for (sigma, tau, ior) in [
            (0.05, 2.0, 1.5),
            (0.3, 3.0, 1.5),
            (1.0, 5.0, 2.5),
            (0.2, 1.0, 20.0),
        ] {
            let model = Htsg {
                kd: [0.0; 3],
                ks: [1.0; 3],
                sigma,
                tau,
                ior,
            };
            for deg in [0.0f64, 30.0, 60.0, 80.0] {
                for v in directional_albedo(&model, deg.to_radians(), 128, 256) {
                    assert!(
                        v.is_finite() && v <= 1.0,
                        "σ {sigma} τ {tau}: albedo {v} at {deg}°"
                    );
                }
            }
        }
    }

    #[test]
    fn shorter_wavelengths_see_a_rougher_surface() {
        // A slightly rough surface (σ₀ well below λ): the coherent spike keeps a share e^{-g}
        // that shrinks as λ shortens, so the diffuse lobe gathers more energy in blue than in
        // green, and more in green than in red.
        let model = Htsg {
            kd: [0.0; 3],
            ks: [1.0; 3],
            sigma: 0.03,
            tau: 2.0,
            ior: 1.5,
        };
        let a = directional_albedo(&model, 0.5, 128, 256);
        assert!(a[2] > a[1] && a[1] > a[0], "{a:?}");
    }
}
