//! Summaries of a BRDF: directional albedo, peak value, reciprocity residual, missing bins.

use crate::coords::{Spherical, Vec3};
use crate::table::MerlTable;
use crate::{Brdf, Rgb};
use rand::{Rng, SeedableRng};
use rayon::prelude::*;
use serde::Serialize;
use std::f64::consts::{FRAC_PI_2, PI, TAU};

/// The albedo quadrature's resolution used wherever a caller has no reason to choose another
/// (`gantry info`, the traits' validity checks): `n_u × n_phi` cells of [`albedo_cells`].
/// Against a 1024 × 1024 quadrature on the embedded MERL tables (a test measures it, θi from 0°
/// to 80°): within 0.25 % for blue-acrylic and pink-felt, within 1.6 % for chrome, whose mirror
/// peak lies inside the first θh bins (64 × 64 cells: 1.2 % and 5.6 %; 512 × 512: 0.15 % and
/// 0.9 %).
pub const ALBEDO_CELLS: (usize, usize) = (256, 256);

/// The cells of the directional-albedo quadrature for light at polar angle `theta_i` (azimuth
/// 0): `(ωo, weight)` with `Σ f(ωi, ωo) · weight ≈ ∫ f(ωi, ωo) cos θo dωo`, row `iu` (of
/// `n_u`) by row — the one rule behind [`directional_albedo`] and every tabulated albedo
/// check.
///
/// The integral is taken over the half vector h rather than ωo (ωo = 2(ωi·h)h − ωi, with
/// dωo = 4 (ωi·h) dωh), on a midpoint grid of `n_u` × `n_phi` cells where θh = u² · π/2 — the
/// same square-root spacing as the MERL grid — so that mirror-like peaks are resolved. Cells
/// whose ωo falls below the horizon are left out.
pub fn albedo_cells(theta_i: f64, n_u: usize, n_phi: usize, iu: usize) -> Vec<(Vec3, f64)> {
    let wi = Spherical::new(theta_i, 0.0).to_vector();
    let du = 1.0 / n_u.max(1) as f64;
    let dphi = TAU / n_phi.max(1) as f64;
    let u = (iu as f64 + 0.5) * du;
    let theta_h = u * u * FRAC_PI_2;
    // dωh = sin θh dθh dφh with dθh = π u du.
    let jac_h = theta_h.sin() * PI * u * du * dphi;
    let mut cells = Vec::with_capacity(n_phi);
    if wi.z < 0.0 {
        return cells;
    }
    for ip in 0..n_phi {
        let phi = (ip as f64 + 0.5) * dphi;
        let h = Spherical::new(theta_h, phi).to_vector();
        let ih = wi.dot(&h);
        if ih <= 0.0 {
            continue;
        }
        let wo = 2.0 * ih * h - wi;
        if wo.z <= 0.0 {
            continue;
        }
        cells.push((wo, wo.z * 4.0 * ih * jac_h));
    }
    cells
}

/// Directional albedo ∫ f(ωi, ωo) cos θo dωo for light at polar angle `theta_i` (azimuth 0), per
/// channel, by the quadrature of [`albedo_cells`] with `n_u` × `n_phi` cells
/// ([`ALBEDO_CELLS`] unless there is a reason for another).
pub fn directional_albedo(brdf: &dyn Brdf, theta_i: f64, n_u: usize, n_phi: usize) -> Rgb {
    let wi = Spherical::new(theta_i, 0.0).to_vector();
    let rows: Vec<Rgb> = (0..n_u)
        .into_par_iter()
        .map(|iu| {
            let mut acc = [0.0; 3];
            for (wo, w) in albedo_cells(theta_i, n_u, n_phi, iu) {
                let f = brdf.eval(&wi, &wo);
                for c in 0..3 {
                    acc[c] += f[c] * w;
                }
            }
            acc
        })
        .collect();
    let mut out = [0.0; 3];
    for r in rows {
        for c in 0..3 {
            out[c] += r[c];
        }
    }
    out
}

/// Relative RMS difference between f(ωi, ωo) and f(ωo, ωi) over `n` seeded random pairs in the
/// upper hemisphere: 0 for a reciprocal BRDF.
pub fn reciprocity_residual(brdf: &dyn Brdf, n: usize, seed: u64) -> f64 {
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed);
    let mut dir = || {
        Spherical::new(
            (rng.gen::<f64>()).acos().min(FRAC_PI_2),
            rng.gen_range(0.0..TAU),
        )
        .to_vector()
    };
    let pairs: Vec<(Vec3, Vec3)> = (0..n).map(|_| (dir(), dir())).collect();
    let (num, den) = pairs
        .par_iter()
        .map(|(wi, wo)| {
            let a = brdf.eval(wi, wo);
            let b = brdf.eval(wo, wi);
            let mut num = 0.0;
            let mut den = 0.0;
            for c in 0..3 {
                num += (a[c] - b[c]).powi(2);
                den += 0.5 * (a[c] * a[c] + b[c] * b[c]);
            }
            (num, den)
        })
        .reduce(|| (0.0, 0.0), |x, y| (x.0 + y.0, x.1 + y.1));
    if den > 0.0 {
        (num / den).sqrt()
    } else {
        0.0
    }
}

/// Albedo at one incidence angle.
#[derive(Debug, Clone, Serialize)]
pub struct AlbedoSample {
    /// Incidence polar angle, degrees.
    pub theta_i_deg: f64,
    /// Directional albedo per channel.
    pub albedo: Rgb,
}

/// A summary of a BRDF, as printed by `gantry info`: [`summarize`]'s result.
///
/// # Examples
///
/// ```
/// use brdf::{summarize, MerlTable, SummaryOptions, BINS};
///
/// let lambert = brdf::load("lambert:kd=0.6").unwrap();
/// // a coarse quadrature keeps the example fast; a constant table stands in for the tabulation
/// let table = MerlTable::from_values(vec![0.6 / std::f64::consts::PI; 3 * BINS]).unwrap();
/// let opts = SummaryOptions {
///     theta_i_deg: vec![0.0, 60.0],
///     n_u: 32,
///     n_phi: 32,
///     reciprocity_pairs: 100,
/// };
/// let s = summarize(&lambert, &table, &opts);
/// // a Lambertian surface reflects its albedo at every incidence angle
/// assert!(s.albedo.iter().all(|a| (a.albedo[0] - 0.6).abs() < 0.01));
/// assert!(s.reciprocity_residual < 1e-12);
/// assert_eq!(s.missing_fraction, 0.0);
/// assert!(s.to_string().contains("directional albedo"));
/// ```
#[derive(Debug, Clone, Serialize)]
pub struct Summary {
    /// Name of the material.
    pub name: String,
    /// Directional albedo against incidence angle.
    pub albedo: Vec<AlbedoSample>,
    /// Largest value per channel on the MERL grid (1/sr).
    pub peak: Rgb,
    /// Relative RMS reciprocity residual over random direction pairs.
    pub reciprocity_residual: f64,
    /// Fraction of (channel, bin) values without data on the MERL grid.
    pub missing_fraction: f64,
    /// Whether the model depends only on (θh, θd, φd).
    pub isotropic: bool,
}

impl std::fmt::Display for Summary {
    /// The text `gantry info` prints: name, isotropy, peak, reciprocity, missing bins and the
    /// albedo table.
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        writeln!(f, "material: {}", self.name)?;
        writeln!(f, "isotropic: {}", self.isotropic)?;
        let [r, g, b] = self.peak;
        writeln!(f, "peak (1/sr): R {r:.6e}  G {g:.6e}  B {b:.6e}")?;
        writeln!(
            f,
            "reciprocity residual (relative RMS): {:.3e}",
            self.reciprocity_residual
        )?;
        writeln!(f, "missing bins: {:.4}%", 100.0 * self.missing_fraction)?;
        writeln!(f, "directional albedo:")?;
        write!(f, "  theta_i      R        G        B")?;
        for a in &self.albedo {
            let [r, g, b] = a.albedo;
            write!(f, "\n  {:5.1}°  {r:8.5} {g:8.5} {b:8.5}", a.theta_i_deg)?;
        }
        Ok(())
    }
}

/// Options of [`summarize`].
#[derive(Debug, Clone)]
pub struct SummaryOptions {
    /// Incidence angles (degrees) at which albedo is computed.
    pub theta_i_deg: Vec<f64>,
    /// Quadrature cells in u = sin²θo.
    pub n_u: usize,
    /// Quadrature cells in φo.
    pub n_phi: usize,
    /// Random pairs for the reciprocity residual.
    pub reciprocity_pairs: usize,
}

impl Default for SummaryOptions {
    fn default() -> Self {
        Self {
            theta_i_deg: (0..9).map(|k| k as f64 * 10.0).chain([85.0]).collect(),
            n_u: ALBEDO_CELLS.0,
            n_phi: ALBEDO_CELLS.1,
            reciprocity_pairs: 20_000,
        }
    }
}

/// Summarises a BRDF. `table` is its tabulation on the MERL grid (for the peak and the missing
/// fraction).
pub fn summarize(brdf: &dyn Brdf, table: &MerlTable, opts: &SummaryOptions) -> Summary {
    let albedo = opts
        .theta_i_deg
        .iter()
        .map(|&d| AlbedoSample {
            theta_i_deg: d,
            albedo: directional_albedo(brdf, d.to_radians().min(FRAC_PI_2), opts.n_u, opts.n_phi),
        })
        .collect();
    Summary {
        name: brdf.name(),
        albedo,
        peak: table.peak(),
        reciprocity_residual: reciprocity_residual(brdf, opts.reciprocity_pairs, 1),
        missing_fraction: table.missing_fraction(),
        isotropic: brdf.is_isotropic(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::analytic::{BlinnPhong, Lambert};

    /// The accuracy [`ALBEDO_CELLS`] states: on the embedded MERL tables its albedo is within
    /// 0.25 % of a 1024 × 1024 quadrature at every incidence angle up to 80°, 1.6 % for the
    /// mirror-like chrome.
    #[test]
    fn the_default_albedo_resolution_stays_close_to_a_fine_reference() {
        let (n_u, n_phi) = ALBEDO_CELLS;
        for name in crate::nbrdf::EMBEDDED_MERL {
            let mut worst: f64 = 0.0;
            let table = crate::spec::load(&format!("merl:{name}"))
                .unwrap()
                .tabulate();
            for deg in [0.0f64, 20.0, 40.0, 60.0, 80.0] {
                let t = deg.to_radians();
                let fine = directional_albedo(&table, t, 1024, 1024);
                let coarse = directional_albedo(&table, t, n_u, n_phi);
                for c in 0..3 {
                    assert!(fine[c] > 0.0);
                    worst = worst.max((coarse[c] - fine[c]).abs() / fine[c]);
                }
            }
            eprintln!("{name}: largest relative albedo difference to 1024 x 1024: {worst:.2e}");
            let bound = if name == "chrome" { 0.016 } else { 0.0025 };
            assert!(worst <= bound, "{name}: {worst}");
        }
    }

    #[test]
    fn reciprocity_residual_detects_non_reciprocal_models() {
        struct OneWay;
        impl Brdf for OneWay {
            fn eval(&self, wi: &Vec3, wo: &Vec3) -> Rgb {
                [wi.z * (1.0 + wo.x.abs()); 3]
            }
            fn name(&self) -> String {
                "one-way".into()
            }
        }
        assert!(reciprocity_residual(&OneWay, 2000, 3) > 0.1);
        let lambert = Lambert { kd: [0.5; 3] };
        assert_eq!(reciprocity_residual(&lambert, 2000, 3), 0.0);
    }

    #[test]
    fn summary_of_a_table_reports_missing_bins_and_peak() {
        let blinn = BlinnPhong {
            kd: [0.1; 3],
            ks: [0.2; 3],
            exponent: 40.0,
        };
        let mut t = MerlTable::tabulate(&blinn);
        for bin in 0..1000 {
            t.set(0, bin, -1.0);
        }
        let opts = SummaryOptions {
            theta_i_deg: vec![0.0, 45.0],
            n_u: 32,
            n_phi: 32,
            reciprocity_pairs: 500,
        };
        let s = summarize(&t, &t, &opts);
        assert!((s.missing_fraction - 1000.0 / (3.0 * crate::table::BINS as f64)).abs() < 1e-12);
        // The peak of Blinn-Phong is at θh = 0: kd/π + ks (n + 8)/(8π).
        let expect = 0.1 / PI + 0.2 * 48.0 / (8.0 * PI);
        assert!((s.peak[1] - expect).abs() < 1e-9 * expect, "{:?}", s.peak);
        assert_eq!(s.albedo.len(), 2);
    }
}
