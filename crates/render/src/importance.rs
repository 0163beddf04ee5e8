//! Importance sampling of tabulated isotropic BRDFs (thesis appendix A.2.4).

use crate::distribution::{AliasTable, Distribution1D};
use crate::sampling::{
    cosine_hemisphere, cosine_hemisphere_pdf, uniform, uniform_hemisphere, uniform_hemisphere_pdf,
    SampleRng,
};
use brdf::{Brdf, Rgb, Vec3};
use rayon::prelude::*;
use std::f64::consts::{FRAC_PI_2, PI, TAU};
use std::sync::Arc;

/// Resolution of the importance tables.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct ImportanceResolution {
    /// Rows over the reflected polar angle θr ∈ [0, π/2].
    pub theta_r: usize,
    /// Cells over the incident polar angle θi ∈ [0, π/2].
    pub theta_i: usize,
    /// Cells over the azimuth difference φdiff ∈ [0, π].
    pub phi_diff: usize,
    /// Sub-samples per cell side used to average the BRDF inside a cell.
    pub supersample: usize,
}

impl Default for ImportanceResolution {
    /// 90 × 90 × 180 cells (1° in every angle) with 2 × 2 sub-samples.
    fn default() -> Self {
        Self {
            theta_r: 90,
            theta_i: 90,
            phi_diff: 180,
            supersample: 2,
        }
    }
}

/// How the φdiff coordinate is drawn once θi is chosen (thesis A.2.4 offers both).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum PhiSampling {
    /// Binary search in the stored conditional CDF `P(φdiff | θr, θi)`.
    #[default]
    Inversion,
    /// Uniform bin plus acceptance test against `M(θr, θi)` (A.12); no CDF needed.
    Rejection,
}

/// Importance-sampling tables of one isotropic BRDF (thesis A.2.4).
///
/// For each reflected polar angle θr (a row of the table) the density
/// `p(θi, φdiff | θr) ∝ f_sum(θr, θi, φdiff) cos θi` (A.10) is stored as a marginal over θi
/// (A.11) and, per (θr, θi), either a conditional CDF over φdiff (transformation method) or the
/// maximum `M(θr, θi)` of A.12 for rejection sampling. `f_sum` is the sum of the red, green and
/// blue BRDF values (A.9).
///
/// The cells are uniform in θi and φdiff; within a cell, directions are drawn uniformly in solid
/// angle, so the density is piecewise constant in solid angle and can be evaluated exactly
/// (needed for unbiased estimates and for multiple importance sampling). Cell weights include
/// the cell's solid angle, which the thesis's A.10/A.11 leave implicit. Isotropy gives
/// `f(θr, θi, φdiff) = f(θr, θi, −φdiff)`, so only φdiff ∈ [0, π] is stored and the sign is
/// drawn with probability ½. A small *defensive* fraction of cosine-weighted samples keeps the
/// density positive wherever the BRDF could be non-zero.
///
/// # Examples
///
/// ```
/// use brdf::Vec3;
/// use rand::SeedableRng;
/// use render::{uniform, BrdfImportance, ImportanceResolution, PhiSampling, SampleRng};
///
/// let lambert = brdf::load("lambert:kd=0.5").unwrap();
/// let res = ImportanceResolution { theta_r: 16, theta_i: 16, phi_diff: 32, supersample: 1 };
/// let tables = BrdfImportance::build(&lambert, res);
/// // Every marginal CDF rises to one.
/// let cdf = tables.marginal_cdf();
/// assert!(cdf.chunks(res.theta_i + 1).all(|row| (row[res.theta_i] - 1.0).abs() < 1e-9));
///
/// let wo = Vec3::new(0.3, 0.2, 0.93).normalize();
/// let mut rng = SampleRng::seed_from_u64(3);
/// // Each sample's density is the one pdf() reports, and the estimate of the albedo
/// // ∫ f cos θi dωi is kd (the density follows f cos θi closely, so it is nearly exact).
/// let n = 2000;
/// let mut albedo = 0.0;
/// for _ in 0..n {
///     let (wi, pdf) = tables.sample(&wo, PhiSampling::Inversion, &mut rng).unwrap();
///     assert!((pdf - tables.pdf(&wo, &wi)).abs() <= 1e-9 * pdf);
///     albedo += 0.5 / std::f64::consts::PI * wi.z / pdf / n as f64;
/// }
/// assert!((albedo - 0.5).abs() < 0.01, "{albedo}");
/// // The density integrates to one over the hemisphere (uniform directions, pdf 1/2π).
/// let mut total = 0.0;
/// for _ in 0..n {
///     let (u1, u2) = (uniform(&mut rng), uniform(&mut rng));
///     let (z, phi) = (u1, std::f64::consts::TAU * u2);
///     let r = (1.0 - z * z).sqrt();
///     let wi = Vec3::new(r * phi.cos(), r * phi.sin(), z);
///     total += tables.pdf(&wo, &wi) * std::f64::consts::TAU / n as f64;
/// }
/// assert!((total - 1.0).abs() < 0.05, "{total}");
/// ```
#[derive(Debug, Clone)]
pub struct BrdfImportance {
    res: ImportanceResolution,
    /// Cell weights `[r][a][k]`: mean of `f_sum cos θi` over the cell times its solid angle.
    cell: Vec<f32>,
    /// Conditional CDFs `[r][a][k]` (value at the upper edge of cell k), normalised to 1.
    cond_cdf: Vec<f32>,
    /// `M(θr, θi)`: the largest cell weight of each (r, a) row.
    row_max: Vec<f32>,
    /// Marginal over θi for each θr row (`None` when the row is all zero).
    marginal: Vec<Option<Distribution1D>>,
    /// Sum of all weights of each θr row (one half of the φdiff range).
    total: Vec<f64>,
    /// cos θ at the θi cell edges.
    cos_edges: Vec<f64>,
    defensive: f64,
}

impl BrdfImportance {
    /// Default fraction of cosine-weighted samples mixed in.
    pub const DEFAULT_DEFENSIVE: f64 = 0.05;

    /// Tabulates `brdf` into importance tables. `brdf` is evaluated `θr·θi·φdiff·supersample²`
    /// times (in parallel), so pass a tabulated BRDF for speed.
    pub fn build(brdf: &dyn Brdf, res: ImportanceResolution) -> Self {
        let res = ImportanceResolution {
            theta_r: res.theta_r.max(1),
            theta_i: res.theta_i.max(1),
            phi_diff: res.phi_diff.max(1),
            supersample: res.supersample.max(1),
        };
        let (nr, na, nk, ss) = (res.theta_r, res.theta_i, res.phi_diff, res.supersample);
        let dtheta = FRAC_PI_2 / na as f64;
        let dphi = PI / nk as f64;
        let cos_edges: Vec<f64> = (0..=na).map(|a| (a as f64 * dtheta).cos()).collect();
        let rows: Vec<Vec<f32>> = (0..nr)
            .into_par_iter()
            .map(|r| {
                let theta_r = (r as f64 + 0.5) / nr as f64 * FRAC_PI_2;
                let wo = Vec3::new(theta_r.sin(), 0.0, theta_r.cos());
                let mut out = vec![0f32; na * nk];
                for a in 0..na {
                    let solid = (cos_edges[a] - cos_edges[a + 1]) * dphi;
                    for k in 0..nk {
                        let mut acc = 0.0;
                        for si in 0..ss {
                            let ti = (a as f64 + (si as f64 + 0.5) / ss as f64) * dtheta;
                            let (st, ct) = ti.sin_cos();
                            for sj in 0..ss {
                                let pd = (k as f64 + (sj as f64 + 0.5) / ss as f64) * dphi;
                                let wi = Vec3::new(st * pd.cos(), st * pd.sin(), ct);
                                let f = brdf.eval(&wi, &wo);
                                acc += f_sum(&f) * ct;
                            }
                        }
                        out[a * nk + k] = (acc / (ss * ss) as f64 * solid) as f32;
                    }
                }
                out
            })
            .collect();
        let mut cell = Vec::with_capacity(nr * na * nk);
        for row in rows {
            cell.extend(row);
        }
        let mut cond_cdf = vec![0f32; nr * na * nk];
        let mut row_max = vec![0f32; nr * na];
        let mut marginal = Vec::with_capacity(nr);
        let mut total = vec![0.0; nr];
        for r in 0..nr {
            let mut sums = vec![0.0; na];
            for a in 0..na {
                let base = (r * na + a) * nk;
                let w = &cell[base..base + nk];
                let s: f64 = w.iter().map(|&x| x as f64).sum();
                sums[a] = s;
                row_max[r * na + a] = w.iter().cloned().fold(0f32, f32::max);
                let mut acc = 0.0;
                for k in 0..nk {
                    acc += w[k] as f64;
                    cond_cdf[base + k] = if s > 0.0 { (acc / s) as f32 } else { 0.0 };
                }
                if s > 0.0 {
                    cond_cdf[base + nk - 1] = 1.0;
                }
            }
            total[r] = sums.iter().sum();
            marginal.push(Distribution1D::new(&sums));
        }
        tracing::debug!(name = %brdf.name(), ?res, "built importance tables");
        Self {
            res,
            cell,
            cond_cdf,
            row_max,
            marginal,
            total,
            cos_edges,
            defensive: Self::DEFAULT_DEFENSIVE,
        }
    }

    /// Sets the fraction of cosine-weighted samples (clamped to `[0, 1]`).
    pub fn with_defensive(mut self, fraction: f64) -> Self {
        self.defensive = if fraction.is_finite() {
            fraction.clamp(0.0, 1.0)
        } else {
            Self::DEFAULT_DEFENSIVE
        };
        self
    }

    /// The table resolution.
    pub fn resolution(&self) -> ImportanceResolution {
        self.res
    }

    /// Cell weights, row-major `[θr row][θi cell][φdiff cell]`: the mean of `f_sum cos θi` over
    /// each cell times its solid angle (the unnormalised density of thesis A.10 over φdiff ∈ [0, π]).
    pub fn cell_weights(&self) -> &[f32] {
        &self.cell
    }

    /// Conditional CDFs over φdiff (layout of [`Self::cell_weights`]), the value at the upper edge
    /// of each cell, normalised to 1 (all zero where a (θr, θi) row has no weight).
    pub fn conditional_cdf(&self) -> &[f32] {
        &self.cond_cdf
    }

    /// Marginal CDFs over θi (thesis A.11): `theta_r × (theta_i + 1)` values, row-major, each
    /// row rising from 0 to 1 at the θi cell edges; a row without weight is all zero.
    pub fn marginal_cdf(&self) -> Vec<f64> {
        let na = self.res.theta_i;
        let mut out = Vec::with_capacity(self.res.theta_r * (na + 1));
        for m in &self.marginal {
            match m {
                Some(d) => out.extend_from_slice(d.cdf()),
                None => out.extend(std::iter::repeat_n(0.0, na + 1)),
            }
        }
        out
    }

    /// Sum of the cell weights of each θr row.
    pub fn row_totals(&self) -> &[f64] {
        &self.total
    }

    /// The fraction of cosine-weighted samples mixed into [`Self::sample`].
    pub fn defensive(&self) -> f64 {
        self.defensive
    }

    /// Bytes held by the tables (the CDF part is the thesis's "comparable to the BRDF" cost).
    pub fn memory_bytes(&self) -> usize {
        (self.cell.len() + self.cond_cdf.len() + self.row_max.len()) * 4
            + self.total.len() * 8
            + self.marginal.len() * (self.res.theta_i + 1) * 16
    }

    /// The same density as alias tables and per-cell densities, for samplers that cannot afford
    /// a CDF search per draw (the vectorised Mitsuba plugin reads them on the device).
    pub fn alias_tables(&self) -> ImportanceAliasTables {
        let (nr, na, nk) = (self.res.theta_r, self.res.theta_i, self.res.phi_diff);
        let mut marginal = Vec::with_capacity(nr * na * 2);
        let mut conditional = Vec::with_capacity(nr * na * nk * 2);
        let mut cell_density = vec![0f32; nr * na * nk];
        let own = |n: usize| (0..n).flat_map(|i| [1.0, i as f32]).collect::<Vec<f32>>();
        for r in 0..nr {
            let total = self.total[r];
            let sums: Vec<f64> = (0..na)
                .map(|a| {
                    let base = (r * na + a) * nk;
                    self.cell[base..base + nk].iter().map(|&w| w as f64).sum()
                })
                .collect();
            match AliasTable::new(&sums) {
                Some(t) if total > 0.0 => marginal.extend(
                    t.threshold()
                        .iter()
                        .zip(t.alias())
                        .flat_map(|(&p, &i)| [p, i as f32]),
                ),
                _ => marginal.extend(own(na)),
            }
            for a in 0..na {
                let base = (r * na + a) * nk;
                let solid = (self.cos_edges[a] - self.cos_edges[a + 1]) * PI / nk as f64;
                for k in 0..nk {
                    if total > 0.0 {
                        cell_density[base + k] =
                            (self.cell[base + k] as f64 / (2.0 * total * solid)) as f32;
                    }
                }
                let weights: Vec<f64> = self.cell[base..base + nk]
                    .iter()
                    .map(|&w| w as f64)
                    .collect();
                let pairs = match AliasTable::new(&weights) {
                    Some(t) if total > 0.0 => t
                        .threshold()
                        .iter()
                        .zip(t.alias())
                        .map(|(&p, &i)| (p, i as usize))
                        .collect::<Vec<_>>(),
                    _ => (0..nk).map(|k| (1.0, k)).collect(),
                };
                conditional.extend(pairs.into_iter().flat_map(|(p, i)| [p, i as f32]));
            }
        }
        ImportanceAliasTables {
            marginal,
            conditional,
            cell_density,
        }
    }

    fn row_of(&self, wo: &Vec3) -> usize {
        let theta_r = polar(wo);
        ((theta_r / FRAC_PI_2 * self.res.theta_r as f64) as usize).min(self.res.theta_r - 1)
    }

    /// Density (solid angle) of [`Self::sample`] for the pair; zero below the horizon.
    pub fn pdf(&self, wo: &Vec3, wi: &Vec3) -> f64 {
        if wo.z <= 0.0 || wi.z <= 0.0 {
            return 0.0;
        }
        let r = self.row_of(wo);
        let cos_pdf = cosine_hemisphere_pdf(wi);
        if self.marginal[r].is_none() {
            return cos_pdf;
        }
        let (na, nk) = (self.res.theta_i, self.res.phi_diff);
        let a = ((polar(wi) / FRAC_PI_2 * na as f64) as usize).min(na - 1);
        let phi_diff = phi_difference(wo, wi);
        let k = ((phi_diff / PI * nk as f64) as usize).min(nk - 1);
        let w = self.cell[(r * na + a) * nk + k] as f64;
        let solid = (self.cos_edges[a] - self.cos_edges[a + 1]) * PI / nk as f64;
        let table = w / (2.0 * self.total[r] * solid);
        (1.0 - self.defensive) * table + self.defensive * cos_pdf
    }

    /// Draws an incident direction for the outgoing direction `wo` (local frame) and returns it
    /// with its density. `None` when `wo` is below the horizon.
    pub fn sample(
        &self,
        wo: &Vec3,
        variant: PhiSampling,
        rng: &mut SampleRng,
    ) -> Option<(Vec3, f64)> {
        if wo.z <= 0.0 {
            return None;
        }
        let r = self.row_of(wo);
        let marginal = match &self.marginal[r] {
            Some(m) if uniform(rng) >= self.defensive => m,
            _ => {
                let wi = cosine_hemisphere(uniform(rng), uniform(rng));
                let p = self.pdf(wo, &wi);
                return (p > 0.0).then_some((wi, p));
            }
        };
        let (na, nk) = (self.res.theta_i, self.res.phi_diff);
        let (a, _) = marginal.sample_discrete(uniform(rng));
        let base = (r * na + a) * nk;
        let k = match variant {
            PhiSampling::Inversion => self.invert_phi(base, uniform(rng)),
            PhiSampling::Rejection => {
                let m = self.row_max[r * na + a] as f64;
                let mut chosen = None;
                for _ in 0..100_000 {
                    let k = ((uniform(rng) * nk as f64) as usize).min(nk - 1);
                    if uniform(rng) * m < self.cell[base + k] as f64 {
                        chosen = Some(k);
                        break;
                    }
                }
                chosen.unwrap_or_else(|| self.invert_phi(base, uniform(rng)))
            }
        };
        let c0 = self.cos_edges[a];
        let c1 = self.cos_edges[a + 1];
        let cos_t = c0 - uniform(rng) * (c0 - c1);
        let sin_t = (1.0 - cos_t * cos_t).max(0.0).sqrt();
        let mut phi_d = (k as f64 + uniform(rng)) * PI / nk as f64;
        if uniform(rng) < 0.5 {
            phi_d = -phi_d;
        }
        let phi = wo.y.atan2(wo.x) + phi_d;
        let wi = Vec3::new(sin_t * phi.cos(), sin_t * phi.sin(), cos_t);
        let p = self.pdf(wo, &wi);
        (p > 0.0 && wi.z > 0.0).then_some((wi, p))
    }

    fn invert_phi(&self, base: usize, u: f64) -> usize {
        let nk = self.res.phi_diff;
        let cdf = &self.cond_cdf[base..base + nk];
        let u = u as f32;
        let k = cdf.partition_point(|&c| c <= u).min(nk - 1);
        // skip empty cells that share the CDF value
        let mut k = k;
        while k + 1 < nk && self.cell[base + k] == 0.0 {
            k += 1;
        }
        k
    }
}

/// [`BrdfImportance`]'s density as alias tables ([`BrdfImportance::alias_tables`]). Rows of
/// θr without weight hold tables that keep every cell and densities of zero (the sampler falls
/// back to the cosine density there, as [`BrdfImportance::pdf`] does).
#[derive(Debug, Clone)]
pub struct ImportanceAliasTables {
    /// `theta_r × theta_i × 2`: per θr row, the alias table over θi cells (A.11), each cell as
    /// (threshold, alias index as `f32`).
    pub marginal: Vec<f32>,
    /// `theta_r × theta_i × phi_diff × 2`: per (θr, θi), the alias table over φdiff cells, each
    /// cell as (threshold, alias index as `f32`).
    pub conditional: Vec<f32>,
    /// `theta_r × theta_i × phi_diff`: the tables' density in solid angle within each cell,
    /// `w / (2 · row total · cell solid angle)`, the part of [`BrdfImportance::pdf`] before the
    /// defensive mixture.
    pub cell_density: Vec<f32>,
}

/// Sum of the RGB channels, negative and non-finite values counted as zero (thesis A.9).
#[inline]
pub fn f_sum(f: &Rgb) -> f64 {
    f.iter()
        .map(|&x| if x.is_finite() && x > 0.0 { x } else { 0.0 })
        .sum()
}

#[inline]
fn polar(v: &Vec3) -> f64 {
    (v.x * v.x + v.y * v.y).sqrt().atan2(v.z)
}

/// |φi − φr| folded into [0, π].
#[inline]
fn phi_difference(wo: &Vec3, wi: &Vec3) -> f64 {
    let d = (wi.y.atan2(wi.x) - wo.y.atan2(wo.x)).rem_euclid(TAU);
    if d > PI {
        TAU - d
    } else {
        d
    }
}

/// The strategy used to pick incident directions at a surface.
#[derive(Clone)]
pub enum DirectionSampler {
    /// Uniform over the hemisphere (thesis A.2.3).
    Uniform,
    /// Cosine-weighted.
    Cosine,
    /// Tabulated BRDF importance sampling (thesis A.2.4).
    Importance {
        /// The tables of the BRDF being sampled.
        table: Arc<BrdfImportance>,
        /// CDF inversion or rejection for φdiff.
        variant: PhiSampling,
    },
    /// The BRDF's own sampler ([`Brdf::sample`]: visible normals for GGX, cosine for Lambert,
    /// cosine for models without one).
    Model(Arc<dyn Brdf>),
}

impl std::fmt::Debug for DirectionSampler {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            DirectionSampler::Uniform => f.write_str("Uniform"),
            DirectionSampler::Cosine => f.write_str("Cosine"),
            DirectionSampler::Importance { variant, .. } => f
                .debug_struct("Importance")
                .field("variant", variant)
                .finish_non_exhaustive(),
            DirectionSampler::Model(brdf) => f.debug_tuple("Model").field(&brdf.name()).finish(),
        }
    }
}

impl DirectionSampler {
    /// Draws an incident direction for `wo` (local frame) with its solid-angle density.
    pub fn sample(&self, wo: &Vec3, rng: &mut SampleRng) -> Option<(Vec3, f64)> {
        match self {
            DirectionSampler::Uniform => {
                let wi = uniform_hemisphere(uniform(rng), uniform(rng));
                Some((wi, uniform_hemisphere_pdf(&wi)))
            }
            DirectionSampler::Cosine => {
                let wi = cosine_hemisphere(uniform(rng), uniform(rng));
                let p = cosine_hemisphere_pdf(&wi);
                (p > 0.0).then_some((wi, p))
            }
            DirectionSampler::Importance { table, variant } => table.sample(wo, *variant, rng),
            DirectionSampler::Model(brdf) => brdf
                .sample(wo, [uniform(rng), uniform(rng), uniform(rng)])
                .map(|s| (s.wi, s.pdf)),
        }
    }

    /// Solid-angle density of [`Self::sample`].
    pub fn pdf(&self, wo: &Vec3, wi: &Vec3) -> f64 {
        match self {
            DirectionSampler::Uniform => uniform_hemisphere_pdf(wi),
            DirectionSampler::Cosine => cosine_hemisphere_pdf(wi),
            DirectionSampler::Importance { table, .. } => table.pdf(wo, wi),
            DirectionSampler::Model(brdf) => brdf.pdf(wi, wo),
        }
    }
}

/// Mean and per-sample variance of a Monte Carlo estimator (thesis A.4–A.5).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct EstimatorStats {
    /// Sample mean per channel.
    pub mean: Rgb,
    /// Unbiased per-sample variance per channel (`Var[f/p]` of A.5).
    pub variance: Rgb,
    /// Number of samples.
    pub samples: usize,
}

impl EstimatorStats {
    /// Standard error of the mean per channel.
    pub fn standard_error(&self) -> Rgb {
        let n = self.samples.max(1) as f64;
        self.variance.map(|v| (v / n).sqrt())
    }

    /// Per-sample variance summed over the channels.
    pub fn total_variance(&self) -> f64 {
        self.variance.iter().sum()
    }
}

/// Estimates the reflected radiance `L_r(wo) = ∫ f(wi, wo) L_i(wi) cos θi dωi` (A.2) with `n`
/// samples of `sampler` (estimator A.8). `radiance` gives `L_i` for local directions.
pub fn estimate_reflected_radiance(
    brdf: &dyn Brdf,
    sampler: &DirectionSampler,
    wo: &Vec3,
    radiance: &dyn Fn(&Vec3) -> Rgb,
    n: usize,
    rng: &mut SampleRng,
) -> EstimatorStats {
    let mut sum = [0.0; 3];
    let mut sum2 = [0.0; 3];
    for _ in 0..n {
        if let Some((wi, p)) = sampler.sample(wo, rng) {
            let f = brdf.eval(&wi, wo);
            let l = radiance(&wi);
            for c in 0..3 {
                let x = f[c].max(0.0) * l[c] * wi.z / p;
                if x.is_finite() {
                    sum[c] += x;
                    sum2[c] += x * x;
                }
            }
        }
    }
    let nf = n.max(1) as f64;
    let mean = sum.map(|s| s / nf);
    let mut variance = [0.0; 3];
    for c in 0..3 {
        variance[c] = if n > 1 {
            ((sum2[c] - nf * mean[c] * mean[c]) / (nf - 1.0)).max(0.0)
        } else {
            0.0
        };
    }
    EstimatorStats {
        mean,
        variance,
        samples: n,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::SeedableRng;

    struct Lobe;
    impl Brdf for Lobe {
        fn eval(&self, wi: &Vec3, wo: &Vec3) -> Rgb {
            if wi.z <= 0.0 || wo.z <= 0.0 {
                return [0.0; 3];
            }
            let r = Vec3::new(-wo.x, -wo.y, wo.z);
            let c = wi.dot(&r).max(0.0);
            let v = 0.1 + 20.0 * c.powi(60);
            [v, 0.5 * v, 0.25 * v]
        }
        fn name(&self) -> String {
            "lobe".into()
        }
    }

    /// The lobe's tables at `[θr, θi, φdiff]` cells with `ss × ss` sub-samples.
    fn lobe_tables(cells: [usize; 3], ss: usize) -> BrdfImportance {
        let [theta_r, theta_i, phi_diff] = cells;
        let res = ImportanceResolution {
            theta_r,
            theta_i,
            phi_diff,
            supersample: ss,
        };
        BrdfImportance::build(&Lobe, res)
    }

    #[test]
    fn exported_tables_reproduce_the_density() {
        let t = lobe_tables([6, 10, 20], 1);
        let (nr, na, nk) = (6, 10, 20);
        assert_eq!(t.cell_weights().len(), nr * na * nk);
        assert_eq!(t.conditional_cdf().len(), nr * na * nk);
        let marginal = t.marginal_cdf();
        assert_eq!(marginal.len(), nr * (na + 1));
        for r in 0..nr {
            assert_eq!(marginal[r * (na + 1)], 0.0);
            assert!((marginal[r * (na + 1) + na] - 1.0).abs() < 1e-12);
        }
        // the density written from the exported tables, as a renderer outside this crate would
        let wo = Vec3::new(0.3, -0.1, 0.9).normalize();
        let wi = Vec3::new(-0.4, 0.2, 0.7).normalize();
        let r = ((polar(&wo) / FRAC_PI_2 * nr as f64) as usize).min(nr - 1);
        let a = ((polar(&wi) / FRAC_PI_2 * na as f64) as usize).min(na - 1);
        let k = ((phi_difference(&wo, &wi) / PI * nk as f64) as usize).min(nk - 1);
        let c0 = (a as f64 * FRAC_PI_2 / na as f64).cos();
        let c1 = ((a + 1) as f64 * FRAC_PI_2 / na as f64).cos();
        let solid = (c0 - c1) * PI / nk as f64;
        let w = t.cell_weights()[(r * na + a) * nk + k] as f64;
        let table = w / (2.0 * t.row_totals()[r] * solid);
        let d = t.defensive();
        let want = (1.0 - d) * table + d * wi.z / PI;
        assert!((t.pdf(&wo, &wi) - want).abs() < 1e-9 * want);
    }

    #[test]
    fn pdf_integrates_to_one_and_matches_samples() {
        let t = lobe_tables([8, 24, 48], 2);
        let wo = Vec3::new(0.5, 0.2, 0.8).normalize();
        // integral of the pdf over the hemisphere by a fine midpoint rule in (cos θ, φ)
        let (nt, np) = (400, 800);
        let mut s = 0.0;
        for i in 0..nt {
            let ct = (i as f64 + 0.5) / nt as f64;
            let st = (1.0 - ct * ct).sqrt();
            for j in 0..np {
                let ph = (j as f64 + 0.5) / np as f64 * TAU;
                let wi = Vec3::new(st * ph.cos(), st * ph.sin(), ct);
                s += t.pdf(&wo, &wi);
            }
        }
        s *= TAU / (nt * np) as f64;
        assert!((s - 1.0).abs() < 5e-3, "pdf integrates to {s}");
        let mut rng = SampleRng::seed_from_u64(1);
        for variant in [PhiSampling::Inversion, PhiSampling::Rejection] {
            for _ in 0..200 {
                let (wi, p) = t.sample(&wo, variant, &mut rng).unwrap();
                assert!((wi.norm() - 1.0).abs() < 1e-9 && wi.z > 0.0);
                assert!((t.pdf(&wo, &wi) - p).abs() <= 1e-9 * p);
            }
        }
    }

    #[test]
    fn alias_tables_hold_the_same_density() {
        let (nr, na, nk) = (6, 10, 20);
        let t = lobe_tables([nr, na, nk], 1);
        let at = t.alias_tables();
        assert_eq!(at.marginal.len(), nr * na * 2);
        assert_eq!(at.conditional.len(), nr * na * nk * 2);
        // rebuild each alias table from the flat arrays and check the probability of every
        // cell against its weight
        let table_of = |pairs: Vec<(f32, f32)>| {
            let n = pairs.len();
            move |j: usize| {
                let mut p = 0.0;
                for (i, &(t, a)) in pairs.iter().enumerate() {
                    if i == j {
                        p += t as f64;
                    }
                    if a as usize == j && i != j {
                        p += 1.0 - t as f64;
                    }
                }
                p / n as f64
            }
        };
        for r in 0..nr {
            let total = t.row_totals()[r];
            let m = table_of(
                (0..na)
                    .map(|a| {
                        (
                            at.marginal[(r * na + a) * 2],
                            at.marginal[(r * na + a) * 2 + 1],
                        )
                    })
                    .collect(),
            );
            for a in 0..na {
                let base = (r * na + a) * nk;
                let c = table_of(
                    (0..nk)
                        .map(|k| {
                            (
                                at.conditional[(base + k) * 2],
                                at.conditional[(base + k) * 2 + 1],
                            )
                        })
                        .collect(),
                );
                for k in 0..nk {
                    let want = t.cell_weights()[base + k] as f64 / total;
                    let got = m(a) * c(k);
                    assert!(
                        (got - want).abs() < 1e-5 * (1.0 + want),
                        "cell ({r}, {a}, {k}): {got} vs {want}"
                    );
                }
            }
        }
        // the cell densities are pdf() before the defensive mixture
        let mut rng = SampleRng::seed_from_u64(5);
        let d = t.defensive();
        for _ in 0..500 {
            let wo = cosine_hemisphere(uniform(&mut rng), uniform(&mut rng));
            let wi = cosine_hemisphere(uniform(&mut rng), uniform(&mut rng));
            let r = ((polar(&wo) / FRAC_PI_2 * nr as f64) as usize).min(nr - 1);
            let a = ((polar(&wi) / FRAC_PI_2 * na as f64) as usize).min(na - 1);
            let k = ((phi_difference(&wo, &wi) / PI * nk as f64) as usize).min(nk - 1);
            let cell = at.cell_density[(r * na + a) * nk + k] as f64;
            let want = (1.0 - d) * cell + d * wi.z / PI;
            let got = t.pdf(&wo, &wi);
            assert!((got - want).abs() <= 1e-6 * got, "{got} vs {want}");
        }
    }
}
