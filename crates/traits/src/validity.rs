//! Physical validity of a BRDF table (thesis §5.2 and §2.1.3).

use std::collections::HashMap;
use std::f64::consts::FRAC_PI_2;

use brdf::MerlTable;
use brdf::Spherical;
use brdf::{reference_bin, BINS};
use nalgebra::DMatrix;
use serde::Serialize;

use crate::error::{Result, TraitsError};

/// Which validity check a result failed or an edit stopped at.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum Check {
    /// A value below zero.
    NonNegativity,
    /// `f(ωi, ωo) ≠ f(ωo, ωi)`.
    Reciprocity,
    /// Directional albedo above the limit.
    EnergyConservation,
    /// Outside the convex hull of the corpus coordinates.
    ConvexHull,
}

impl std::fmt::Display for Check {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(match self {
            Check::NonNegativity => "non-negativity",
            Check::Reciprocity => "reciprocity",
            Check::EnergyConservation => "energy conservation",
            Check::ConvexHull => "convex hull",
        })
    }
}

/// Settings of the checks.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct ValidityOptions {
    /// Incidence angles (degrees) at which the albedo is checked.
    pub theta_i_deg: Vec<f64>,
    /// Quadrature cells in `u` (θh = u²·π/2).
    pub n_u: usize,
    /// Quadrature cells in φh.
    pub n_phi: usize,
    /// Largest allowed directional albedo.
    pub albedo_limit: f64,
    /// Random direction pairs for the reciprocity residual (0 = skip).
    pub reciprocity_pairs: usize,
    /// Largest allowed reciprocity residual.
    pub reciprocity_tolerance: f64,
}

impl Default for ValidityOptions {
    fn default() -> Self {
        ValidityOptions {
            theta_i_deg: vec![0.0, 15.0, 30.0, 45.0, 60.0, 70.0, 80.0],
            n_u: brdf::ALBEDO_CELLS.0,
            n_phi: brdf::ALBEDO_CELLS.1,
            albedo_limit: 1.0,
            reciprocity_pairs: 256,
            reciprocity_tolerance: 1e-9,
        }
    }
}

/// The result of [`validate`].
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct ValidityReport {
    /// Smallest value over all bins and channels (1/sr).
    pub min_value: f64,
    /// Number of (channel, bin) values below zero.
    pub negative_values: usize,
    /// Directional albedo `[θi][channel]` at [`ValidityOptions::theta_i_deg`].
    pub albedo: Vec<[f64; 3]>,
    /// The largest albedo, and the incidence angle (degrees) and channel where it occurs.
    pub max_albedo: (f64, f64, usize),
    /// Reciprocity residual (0 when skipped).
    pub reciprocity_residual: f64,
    /// Convex-hull membership, when it was tested.
    pub in_hull: Option<bool>,
    /// Checks that failed, in the order non-negativity, reciprocity, energy, hull.
    pub failed: Vec<Check>,
}

impl ValidityReport {
    /// Whether every check passed.
    pub fn is_valid(&self) -> bool {
        self.failed.is_empty()
    }
}

/// Directional-albedo quadrature mapped to table bins, one rule per incidence angle.
#[derive(Debug, Clone)]
pub struct AlbedoQuadrature {
    /// Incidence angles, degrees.
    pub theta_i_deg: Vec<f64>,
    /// For every angle: `(bin, weight)`, bins distinct.
    pub rules: Vec<Vec<(usize, f64)>>,
}

impl AlbedoQuadrature {
    /// Builds the rules: the cells of [`brdf::directional_albedo`] with an `n_u × n_phi`
    /// grid, each mapped to the bin that [`MerlTable`]'s nearest lookup reads, weights of equal
    /// bins merged.
    pub fn new(theta_i_deg: &[f64], n_u: usize, n_phi: usize) -> Result<AlbedoQuadrature> {
        if n_u == 0 || n_phi == 0 || theta_i_deg.is_empty() {
            return Err(TraitsError::InvalidParameter(
                "albedo quadrature needs angles and cells".into(),
            ));
        }
        if theta_i_deg.iter().any(|t| !(0.0..=90.0).contains(t)) {
            return Err(TraitsError::InvalidParameter(
                "incidence angles must lie in [0°, 90°]".into(),
            ));
        }
        let rules = theta_i_deg
            .iter()
            .map(|&deg| {
                let theta_i = deg.to_radians().min(FRAC_PI_2);
                let wi = Spherical::new(theta_i, 0.0).to_vector();
                let mut acc: HashMap<usize, f64> = HashMap::new();
                for iu in 0..n_u {
                    for (wo, w) in brdf::albedo_cells(theta_i, n_u, n_phi, iu) {
                        *acc.entry(reference_bin(&wi, &wo)).or_insert(0.0) += w;
                    }
                }
                let mut v: Vec<(usize, f64)> = acc.into_iter().collect();
                v.sort_by_key(|p| p.0);
                v
            })
            .collect();
        Ok(AlbedoQuadrature {
            theta_i_deg: theta_i_deg.to_vec(),
            rules,
        })
    }

    /// The quadrature of a validity configuration.
    pub fn from_options(o: &ValidityOptions) -> Result<AlbedoQuadrature> {
        AlbedoQuadrature::new(&o.theta_i_deg, o.n_u, o.n_phi)
    }

    /// All distinct bins the rules read (sorted).
    pub fn bins(&self) -> Vec<usize> {
        let mut b: Vec<usize> = self.rules.iter().flatten().map(|p| p.0).collect();
        b.sort_unstable();
        b.dedup();
        b
    }

    /// Albedo `[θi][channel]` of a table (missing bins read as 0, as the table's lookup does).
    pub fn albedo_of_table(&self, table: &MerlTable) -> Vec<[f64; 3]> {
        self.rules
            .iter()
            .map(|rule| {
                let mut a = [0.0; 3];
                for &(bin, w) in rule {
                    if let Some(rgb) = table.bin_rgb(bin) {
                        for c in 0..3 {
                            a[c] += w * rgb[c];
                        }
                    }
                }
                a
            })
            .collect()
    }

    /// Albedo `[θi][channel]` of channel-major BRDF values (`3 × BINS`, 1/sr).
    pub fn albedo_of_values(&self, values: &[f64]) -> Vec<[f64; 3]> {
        self.albedo_by(|c, bin| values[c * BINS + bin])
    }

    /// Albedo `[θi][channel]` with values supplied by `value(channel, bin)`.
    pub fn albedo_by(&self, value: impl Fn(usize, usize) -> f64) -> Vec<[f64; 3]> {
        self.rules
            .iter()
            .map(|rule| {
                let mut a = [0.0; 3];
                for &(bin, w) in rule {
                    for c in 0..3 {
                        a[c] += w * value(c, bin);
                    }
                }
                a
            })
            .collect()
    }
}

/// The largest entry of an albedo list: `(albedo, θi in degrees, channel)`.
pub fn max_albedo(albedo: &[[f64; 3]], theta_i_deg: &[f64]) -> (f64, f64, usize) {
    let mut best = (f64::NEG_INFINITY, 0.0, 0);
    for (a, &t) in albedo.iter().zip(theta_i_deg) {
        for c in 0..3 {
            if a[c] > best.0 || a[c].is_nan() {
                best = (a[c], t, c);
            }
        }
    }
    best
}

/// Checks a table: non-negativity over all bins, reciprocity over seeded random pairs, and the
/// directional albedo at the quadrature's angles. `hull` is the result of a convex-hull test
/// done by the caller on the table's embedding coordinates (see [`in_convex_hull`]), if any.
///
/// These are the checks of physical validity of thesis §5.2 and §2.1.3:
///
/// * **Non-negativity**: every value of the three channels is ≥ 0 (MERL tables mark missing
///   data with negative values, so a missing bin fails too).
/// * **Reciprocity**: the relative RMS difference between `f(ωi, ωo)` and `f(ωo, ωi)` over
///   seeded random pairs ([`brdf::reciprocity_residual`]). Tables on the MERL grid are
///   reciprocal by construction (φd is folded by reciprocity, thesis §5.2), so the check guards
///   the lookup rather than the data.
/// * **Energy conservation**: the directional albedo `∫ f cos θo dωo` is ≤ 1 for every
///   incident direction and channel. It is computed at a coarse set of incidence angles with
///   the quadrature of [`brdf::directional_albedo`] (the half-vector grid with
///   `θh = u²·π/2`), whose cells are mapped to table bins once: [`AlbedoQuadrature`] holds, for
///   every incidence angle, the list of `(bin, weight)` pairs, so the albedo of a table — or of
///   a model point, from a few basis rows only — is a short weighted sum.
/// * **Convex hull** (optional): the point's embedding coordinates are a convex combination of
///   the corpus coordinates (an LP feasibility problem, [`in_convex_hull`]). The thesis argues
///   that inside the hull the other three hold.
///
/// # Examples
///
/// ```
/// use traits::{validate, AlbedoQuadrature, Check, ValidityOptions};
/// let opts = ValidityOptions::default();
/// let quadrature = AlbedoQuadrature::from_options(&opts).unwrap();
/// // A Lambertian surface reflects its albedo kd at every incidence angle.
/// let matte = brdf::load("lambert:kd=0.5").unwrap().tabulate();
/// let report = validate(&matte, &quadrature, &opts, None);
/// assert!(report.is_valid());
/// assert!(report.albedo.iter().flatten().all(|a| (a - 0.5).abs() < 0.01));
/// // Scaled to an albedo of 1.2, the surface would create energy.
/// let scaled = matte.values().iter().map(|v| 2.4 * v).collect();
/// let glowing = brdf::MerlTable::from_values(scaled).unwrap();
/// assert_eq!(validate(&glowing, &quadrature, &opts, None).failed, [Check::EnergyConservation]);
/// // A missing (negative) value fails non-negativity, and a hull test done by the caller counts.
/// let mut holed = matte.clone();
/// holed.set(0, 0, -1.0);
/// let report = validate(&holed, &quadrature, &opts, Some(false));
/// assert_eq!(report.failed, [Check::NonNegativity, Check::ConvexHull]);
/// assert_eq!(report.negative_values, 1);
/// ```
pub fn validate(
    table: &MerlTable,
    quadrature: &AlbedoQuadrature,
    opts: &ValidityOptions,
    hull: Option<bool>,
) -> ValidityReport {
    let raw = table.raw();
    let mut min_value = f64::INFINITY;
    let mut negative_values = 0;
    for (c, ch) in raw.chunks_exact(BINS).enumerate() {
        for &v in ch {
            let v = v * brdf::MERL_SCALE[c];
            if v < min_value || v.is_nan() {
                min_value = v;
            }
            if v < 0.0 || v.is_nan() {
                negative_values += 1;
            }
        }
    }
    let albedo = quadrature.albedo_of_table(table);
    let max_a = max_albedo(&albedo, &quadrature.theta_i_deg);
    let reciprocity_residual = if opts.reciprocity_pairs > 0 {
        brdf::reciprocity_residual(table, opts.reciprocity_pairs, 7)
    } else {
        0.0
    };
    let mut failed = Vec::new();
    if negative_values > 0 {
        failed.push(Check::NonNegativity);
    }
    if reciprocity_residual.is_nan() || reciprocity_residual > opts.reciprocity_tolerance {
        failed.push(Check::Reciprocity);
    }
    if max_a.0.is_nan() || max_a.0 > opts.albedo_limit {
        failed.push(Check::EnergyConservation);
    }
    if hull == Some(false) {
        failed.push(Check::ConvexHull);
    }
    ValidityReport {
        min_value,
        negative_values,
        albedo,
        max_albedo: max_a,
        reciprocity_residual,
        in_hull: hull,
        failed,
    }
}

/// Whether `x` is a convex combination of the rows of `points` (LP feasibility:
/// `Σ λ_i p_i = x`, `Σ λ_i = 1`, `λ ≥ 0`), with equality tolerance relative to the coordinate
/// scale left to the LP solver.
pub fn in_convex_hull(points: &DMatrix<f64>, x: &[f64]) -> Result<bool> {
    Ok(hull_line_search(points, x, &vec![0.0; x.len()], 0.0)?.is_some())
}

/// The largest `t ∈ [0, t_max]` with `x + t·v` inside the convex hull of the rows of `points`
/// (one LP: maximise `t` subject to `Σ λ_i p_i − t v = x`, `Σ λ_i = 1`, `λ ≥ 0`); `None` when
/// `x` itself is outside.
pub fn hull_line_search(
    points: &DMatrix<f64>,
    x: &[f64],
    v: &[f64],
    t_max: f64,
) -> Result<Option<f64>> {
    use microlp::{ComparisonOp, OptimizationDirection, Problem};
    let (n, d) = points.shape();
    if x.len() != d || v.len() != d {
        return Err(TraitsError::Dimension {
            what: "hull point",
            expected: d,
            got: x.len(),
        });
    }
    // Scale every axis by the spread of the points so the solver's tolerances are relative.
    let scale: Vec<f64> = (0..d)
        .map(|k| {
            let c = points.column(k);
            let s = c.max() - c.min();
            if s > 0.0 {
                s
            } else {
                1.0
            }
        })
        .collect();
    let mut p = Problem::new(OptimizationDirection::Maximize);
    let lambdas: Vec<_> = (0..n).map(|_| p.add_var(0.0, (0.0, 1.0))).collect();
    let t = p.add_var(1.0, (0.0, t_max.max(0.0)));
    for k in 0..d {
        let mut row: Vec<(microlp::Variable, f64)> = lambdas
            .iter()
            .enumerate()
            .map(|(i, &l)| (l, points[(i, k)] / scale[k]))
            .collect();
        row.push((t, -v[k] / scale[k]));
        p.add_constraint(&row, ComparisonOp::Eq, x[k] / scale[k]);
    }
    let ones: Vec<(microlp::Variable, f64)> = lambdas.iter().map(|&l| (l, 1.0)).collect();
    p.add_constraint(&ones, ComparisonOp::Eq, 1.0);
    match p.solve() {
        Ok(sol) => Ok(Some(sol[t])),
        Err(microlp::Error::Infeasible) => Ok(None),
        Err(e) => Err(TraitsError::Numerical(format!("hull LP: {e}"))),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use brdf::analytic::{BlinnPhong, Lambert};

    #[test]
    fn quadrature_agrees_with_the_summary_albedo() {
        // The cached rules evaluate exactly the sum brdf::summary computes on the table.
        let t = MerlTable::tabulate(&BlinnPhong {
            kd: [0.2, 0.4, 0.6],
            ks: [0.3; 3],
            exponent: 60.0,
        });
        let angles = [0.0, 37.0, 75.0];
        let q = AlbedoQuadrature::new(&angles, 24, 20).unwrap();
        let a = q.albedo_of_table(&t);
        let vals = q.albedo_of_values(&t.values());
        for (i, &deg) in angles.iter().enumerate() {
            let s = brdf::directional_albedo(&t, deg.to_radians(), 24, 20);
            for c in 0..3 {
                assert!(
                    (a[i][c] - s[c]).abs() <= 1e-12 * s[c].max(1.0),
                    "{deg}: {a:?} {s:?}"
                );
                assert!((vals[i][c] - s[c]).abs() <= 1e-9 * s[c].max(1.0));
            }
        }
    }

    #[test]
    fn lambert_albedo_and_the_three_checks() {
        let q = AlbedoQuadrature::from_options(&ValidityOptions::default()).unwrap();
        let opts = ValidityOptions::default();
        // Lambert with albedo ρ has directional albedo ρ at every angle.
        let ok = MerlTable::tabulate(&Lambert {
            kd: [0.5, 0.7, 0.9],
        });
        let r = validate(&ok, &q, &opts, None);
        assert!(r.is_valid(), "{r:?}");
        for a in &r.albedo {
            for (c, want) in [0.5, 0.7, 0.9].iter().enumerate() {
                assert!((a[c] - want).abs() < 0.03, "{a:?}");
            }
        }
        // Too bright: albedo 1.2 in red.
        let bright = MerlTable::tabulate(&Lambert {
            kd: [1.2, 0.5, 0.5],
        });
        let r = validate(&bright, &q, &opts, Some(true));
        assert_eq!(r.failed, vec![Check::EnergyConservation]);
        assert_eq!(r.max_albedo.2, 0);
        // A negative bin fails non-negativity.
        let mut neg = ok.clone();
        neg.set(1, 12345, -0.01);
        let r = validate(&neg, &q, &opts, Some(false));
        assert_eq!(r.failed, vec![Check::NonNegativity, Check::ConvexHull]);
        assert_eq!(r.negative_values, 1);
    }

    #[test]
    fn tabulated_tables_are_reciprocal() {
        let t = MerlTable::tabulate(&brdf::analytic::Ggx {
            kd: [0.1, 0.2, 0.3],
            ks: [0.5; 3],
            alpha: 0.1,
            ior: 1.5,
        });
        let r = brdf::reciprocity_residual(&t, 256, 7);
        eprintln!("reciprocity residual {r}");
        assert!(r <= ValidityOptions::default().reciprocity_tolerance, "{r}");
    }

    #[test]
    fn any_table_on_the_grid_is_reciprocal() {
        // Swapping ωi and ωo keeps θh and θd and turns φd into φd ± π, which the grid folds
        // onto the same bin: reciprocity holds for arbitrary values, e.g. seeded noise, and
        // hence for every back-projection (PCA or chart) written on this grid.
        use rand::{Rng, SeedableRng};
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(3);
        let values: Vec<f64> = (0..3 * BINS).map(|_| rng.gen_range(0.0..2.0)).collect();
        let t = MerlTable::from_values(values).unwrap();
        let r = brdf::reciprocity_residual(&t, 4096, 11);
        assert_eq!(r, 0.0, "residual {r}");
    }

    #[test]
    fn hull_membership_and_line_search() {
        // The unit square.
        let p = DMatrix::from_row_slice(4, 2, &[0.0, 0.0, 1.0, 0.0, 0.0, 1.0, 1.0, 1.0]);
        assert!(in_convex_hull(&p, &[0.5, 0.5]).unwrap());
        assert!(in_convex_hull(&p, &[1.0, 0.2]).unwrap());
        assert!(!in_convex_hull(&p, &[1.1, 0.5]).unwrap());
        let t = hull_line_search(&p, &[0.25, 0.5], &[1.0, 0.0], 10.0)
            .unwrap()
            .unwrap();
        assert!((t - 0.75).abs() < 1e-9, "{t}");
        assert_eq!(
            hull_line_search(&p, &[2.0, 0.5], &[1.0, 0.0], 1.0).unwrap(),
            None
        );
    }
}
