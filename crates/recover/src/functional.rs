//! Pixels as linear functionals of the unknown BRDF.

use std::f64::consts::{FRAC_PI_2, PI};

use brdf::{MerlTable, Vec3};
use rand::SeedableRng;
use rayon::prelude::*;
use render::Hit;
use render::Ray;
use render::{cosine_hemisphere, cosine_hemisphere_pdf, uniform, Frame, SampleRng};

use crate::error::{RecoverError, Result};
use crate::scene::RecoveryScene;

/// How the functionals are built.
#[derive(Debug, Clone, PartialEq)]
pub struct FunctionalOptions {
    /// Sub-pixel positions per axis for point lights (`n × n` per pixel).
    pub subpixels: usize,
    /// Monte Carlo samples per pixel for the environment map.
    pub env_samples: usize,
    /// Mixture probabilities of the environment proposals: probe luminance, cosine,
    /// half-vector (normalised).
    pub mixture: [f64; 3],
    /// Keep every `stride`-th pixel in x and y (1 = all).
    pub stride: usize,
    /// Seed of the per-pixel random streams.
    pub seed: u64,
    /// How the environment samples of a pixel are placed.
    pub env_sampling: EnvSampling,
}

/// How the environment-map samples of one pixel are placed.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum EnvSampling {
    /// Each sample picks a proposal at random with the mixture probabilities and draws its
    /// sub-pixel position and direction independently (one-sample balance heuristic).
    Independent,
    /// Each proposal gets its share of the samples as a fixed count (largest remainder), and
    /// its directions come from a randomly shifted Hammersley point set, as do the sub-pixel
    /// positions (randomly paired with the directions): the multi-sample balance heuristic,
    /// unbiased, with the variance of stratified points instead of independent ones.
    #[default]
    Stratified,
}

impl Default for FunctionalOptions {
    fn default() -> Self {
        FunctionalOptions {
            subpixels: 2,
            env_samples: 64,
            mixture: [0.4, 0.2, 0.4],
            stride: 1,
            seed: 0x5eed,
            env_sampling: EnvSampling::Stratified,
        }
    }
}

/// The functionals of the pixels of one image that see only the unknown material: a sparse
/// matrix in compressed rows, one row per pixel.
///
/// Under direct light, the radiance of a pixel that sees the unknown material is linear in the
/// BRDF: `I_c = Σ_b w_{b,c} f_c(b)` over MERL bins `b`. For a point light of intensity `I` at
/// distance `r` the weight is `I cos θi / r²` on the single bin of the pair (ωi, ωo) (averaged
/// over a few sub-pixel positions, as the renderer averages over the pixel). For an
/// environment map the weight is a Monte Carlo estimate of `∫ L(ωi) f(ωi, ωo) cos θi dωi`,
/// drawn once per pixel from three proposals weighted by the balance heuristic (unbiased):
/// the probe's luminance, the cosine lobe, and a half-vector proposal with `θh = u² π/2` that
/// puts equally many samples in every θh row of the MERL grid (it resolves mirror-like peaks).
/// How the samples are placed is [`EnvSampling`] (stratified by default). Bins are found with the reference reader's
/// arithmetic, the lookup the renderer uses for nearest-bin tables, in the renderer's shading
/// frame, so a tabulated material's pixel is reproduced exactly up to the Monte Carlo error.
#[derive(Debug, Clone, Default)]
pub struct Functionals {
    /// Image width.
    pub width: usize,
    /// Image height.
    pub height: usize,
    /// Image pixel index (`y · width + x`) of each row.
    pub pixels: Vec<u32>,
    /// Row `r` owns entries `row_ptr[r]..row_ptr[r + 1]`.
    pub row_ptr: Vec<usize>,
    /// MERL bin of each entry.
    pub bins: Vec<u32>,
    /// RGB weight of each entry (radiance per unit BRDF value, 1/sr⁻¹).
    pub weights: Vec<[f32; 3]>,
    /// Whether each image pixel sees the unknown material at all (also at its edge).
    pub coverage: Vec<bool>,
}

/// Material id of a hit if it is one of the unknown materials.
fn unknown_hit(rs: &RecoveryScene, ray: &Ray) -> Option<Hit> {
    let hit = rs.scene.intersect(ray, f64::INFINITY)?;
    let m = hit.material?;
    rs.unknown.contains(&m).then_some(hit)
}

/// The renderer's shading frame and local outgoing direction at a hit.
fn shading(hit: &Hit, to_viewer: &Vec3) -> Option<(Frame, Vec3)> {
    let frame = Frame::from_normal(&hit.shading_normal);
    let wo = frame.to_local(to_viewer);
    if wo.z > 1e-9 {
        return Some((frame, wo));
    }
    let frame = Frame::from_normal(&hit.geometric_normal);
    let wo = frame.to_local(to_viewer);
    (wo.z > 1e-9).then_some((frame, wo))
}

/// MERL bin of a local direction pair, with the reference reader's arithmetic
/// ([`brdf::reference_bin`]).
pub fn merl_bin(wi: &Vec3, wo: &Vec3) -> u32 {
    brdf::reference_bin(wi, wo) as u32
}

fn offset_origin(rs: &RecoveryScene, hit: &Hit, dir: &Vec3) -> Vec3 {
    let scale = 1e-6 * (1.0 + hit.point.amax()) + 1e-7;
    let side = if dir.dot(&hit.geometric_normal) >= 0.0 {
        1.0
    } else {
        -1.0
    };
    let _ = rs;
    hit.point + hit.geometric_normal * (side * scale)
}

fn visible(rs: &RecoveryScene, hit: &Hit, dir: &Vec3, target: Option<&Vec3>) -> bool {
    let origin = offset_origin(rs, hit, dir);
    match target {
        Some(t) => {
            let to = t - origin;
            let dist = to.norm();
            dist > 0.0 && dist.is_finite() && !rs.scene.occluded(&origin, &(to / dist), dist)
        }
        None => !rs.scene.occluded(&origin, dir, f64::INFINITY),
    }
}

/// Density of the half-vector proposal for local directions `wi`, `wo`.
fn half_pdf(wi: &Vec3, wo: &Vec3) -> f64 {
    let h = wi + wo;
    let n = h.norm();
    if n <= 0.0 {
        return 0.0;
    }
    let h = h / n;
    // sin θh from the tangential part and θh by atan2: `acos(h.z)` rounds every θh below
    // about 1.5·10⁻⁸ to 0 (h.z == 1.0), where the density is not 0 but very large. A density
    // of 0 there gave the samples this proposal draws closest to the specular direction the
    // weight of the other proposals alone — weights 10⁴ too large, in the bins where a shiny
    // material's value is largest.
    let s = h.x.hypot(h.y);
    let th = s.atan2(h.z);
    let u = (th / FRAC_PI_2).sqrt();
    let oh = wo.dot(&h);
    if oh <= 0.0 {
        return 0.0;
    }
    if s <= 0.0 || u <= 0.0 {
        // exactly the specular direction: the density is unbounded (the sample's weight is 0)
        return f64::INFINITY;
    }
    // p(u, φ) = 1/(2π); θh = u²π/2 ⇒ p(ωh) = 1 / (2π · π u · sin θh); p(ωi) = p(ωh) / (4 ωo·h).
    1.0 / (2.0 * PI * PI * u * s) / (4.0 * oh)
}

fn sample_half(wo: &Vec3, u1: f64, u2: f64) -> Vec3 {
    let th = u1 * u1 * FRAC_PI_2;
    let ph = 2.0 * PI * u2;
    let h = Vec3::new(th.sin() * ph.cos(), th.sin() * ph.sin(), th.cos());
    2.0 * wo.dot(&h) * h - wo
}

type Entry = (u32, [f32; 3]);
type Row = (u32, Vec<Entry>);
type ImageRow = (Vec<Row>, Vec<(usize, bool)>);

impl Functionals {
    /// Builds the functionals of every pixel that sees only the unknown material.
    pub fn build(rs: &RecoveryScene, opts: &FunctionalOptions) -> Result<Functionals> {
        let cam = &rs.scene.camera;
        let (w, h) = (cam.width, cam.height);
        if opts.subpixels == 0 || opts.stride == 0 {
            return Err(RecoverError::InvalidParameter(
                "subpixels and stride must be positive".into(),
            ));
        }
        if rs.scene.environment.is_some() && opts.env_samples == 0 {
            return Err(RecoverError::InvalidParameter(
                "env_samples must be positive with an environment map".into(),
            ));
        }
        if !rs.scene.area_lights.is_empty() {
            return Err(RecoverError::Scene(
                "area lights are not supported by the pixel model (use point lights or an \
                 environment map)"
                    .into(),
            ));
        }
        if rs.scene.point_lights.is_empty() && rs.scene.environment.is_none() {
            return Err(RecoverError::Scene("the scene has no light".into()));
        }
        let msum: f64 = opts.mixture.iter().sum();
        if msum.partial_cmp(&0.0) != Some(std::cmp::Ordering::Greater)
            || opts.mixture.iter().any(|&m| m < 0.0)
        {
            return Err(RecoverError::InvalidParameter(
                "mixture probabilities must be non-negative with a positive sum".into(),
            ));
        }
        let mix = opts.mixture.map(|m| m / msum);
        let rows: Vec<ImageRow> = (0..h)
            .into_par_iter()
            .map(|y| {
                let mut out = Vec::new();
                let mut cov = Vec::new();
                for x in 0..w {
                    let idx = y * w + x;
                    let mut rng = SampleRng::seed_from_u64(opts.seed);
                    rng.set_stream(idx as u64 + 1);
                    let (row, any) = pixel_row(rs, x, y, opts, mix, &mut rng);
                    cov.push((idx, any));
                    if x % opts.stride != 0 || y % opts.stride != 0 {
                        continue;
                    }
                    if let Some(mut e) = row {
                        e.sort_unstable_by_key(|a| a.0);
                        let mut merged: Vec<(u32, [f32; 3])> = Vec::with_capacity(e.len());
                        for (b, wv) in e {
                            match merged.last_mut() {
                                Some(last) if last.0 == b => {
                                    for c in 0..3 {
                                        last.1[c] += wv[c];
                                    }
                                }
                                _ => merged.push((b, wv)),
                            }
                        }
                        out.push((idx as u32, merged));
                    }
                }
                (out, cov)
            })
            .collect();
        let mut f = Functionals {
            width: w,
            height: h,
            coverage: vec![false; w * h],
            row_ptr: vec![0],
            ..Default::default()
        };
        for (r, cov) in rows {
            for (i, a) in cov {
                f.coverage[i] = a;
            }
            for (p, e) in r {
                f.pixels.push(p);
                for (b, wv) in e {
                    f.bins.push(b);
                    f.weights.push(wv);
                }
                f.row_ptr.push(f.bins.len());
            }
        }
        tracing::debug!(rows = f.len(), entries = f.bins.len(), "functionals built");
        Ok(f)
    }

    /// The rows `r` with `keep(r)` (same image, same coverage).
    pub fn subset(&self, keep: impl Fn(usize) -> bool) -> Functionals {
        let mut f = Functionals {
            width: self.width,
            height: self.height,
            coverage: self.coverage.clone(),
            row_ptr: vec![0],
            ..Default::default()
        };
        for r in (0..self.len()).filter(|&r| keep(r)) {
            f.pixels.push(self.pixels[r]);
            let e = self.row_ptr[r]..self.row_ptr[r + 1];
            f.bins.extend_from_slice(&self.bins[e.clone()]);
            f.weights.extend_from_slice(&self.weights[e]);
            f.row_ptr.push(f.bins.len());
        }
        f
    }

    /// Number of rows (usable pixels).
    pub fn len(&self) -> usize {
        self.pixels.len()
    }

    /// Whether no pixel sees the unknown material.
    pub fn is_empty(&self) -> bool {
        self.pixels.is_empty()
    }

    /// Applies the functionals to BRDF values given per bin: one RGB radiance per row.
    pub fn apply(&self, value: impl Fn(u32) -> [f64; 3] + Sync) -> Vec<[f64; 3]> {
        (0..self.len())
            .into_par_iter()
            .map(|r| {
                let mut acc = [0.0; 3];
                for e in self.row_ptr[r]..self.row_ptr[r + 1] {
                    let v = value(self.bins[e]);
                    let wv = self.weights[e];
                    for c in 0..3 {
                        acc[c] += wv[c] as f64 * v[c];
                    }
                }
                acc
            })
            .collect()
    }

    /// Applies the functionals to a table (missing values count as 0).
    pub fn apply_table(&self, table: &MerlTable) -> Vec<[f64; 3]> {
        self.apply(|b| {
            let b = b as usize;
            [0, 1, 2].map(|c| table.get(c, b).max(0.0))
        })
    }

    /// The radiance each row would see from a white diffuse surface (albedo 1, `f = 1/π`): the
    /// scale of what the scene's lights can make a physical material reflect.
    pub fn white_response(&self) -> Vec<[f64; 3]> {
        self.apply(|_| [std::f64::consts::FRAC_1_PI; 3])
    }

    /// An image with the given row values at the rows' pixels and `background` elsewhere.
    pub fn to_image(&self, rows: &[[f64; 3]], background: Option<&[[f32; 3]]>) -> Vec<[f32; 3]> {
        let mut img = match background {
            Some(b) => b.to_vec(),
            None => vec![[0.0; 3]; self.width * self.height],
        };
        for (p, v) in self.pixels.iter().zip(rows) {
            img[*p as usize] = v.map(|x| x as f32);
        }
        img
    }
}

/// One pixel's entries (`None` when any sample misses the unknown material) and whether any
/// sample hit it.
fn pixel_row(
    rs: &RecoveryScene,
    x: usize,
    y: usize,
    opts: &FunctionalOptions,
    mix: [f64; 3],
    rng: &mut SampleRng,
) -> (Option<Vec<Entry>>, bool) {
    let cam = &rs.scene.camera;
    let mut entries = Vec::new();
    let mut any = false;
    let mut all = true;
    // The unknown material's hit of a camera ray, with its shading frame and the outgoing
    // direction; a ray that misses it makes the pixel unusable.
    let mut trace = |ray: &Ray| {
        let Some(hit) = unknown_hit(rs, ray) else {
            all = false;
            return None;
        };
        any = true;
        let (frame, wo) = shading(&hit, &-ray.direction)?;
        Some((hit, frame, wo))
    };
    let n = opts.subpixels;
    if !rs.scene.point_lights.is_empty() {
        let scale = 1.0 / (n * n) as f64;
        for sy in 0..n {
            for sx in 0..n {
                let ray = cam.ray(
                    x as f64 + (sx as f64 + 0.5) / n as f64,
                    y as f64 + (sy as f64 + 0.5) / n as f64,
                );
                let Some((hit, frame, wo)) = trace(&ray) else {
                    continue;
                };
                for pl in &rs.scene.point_lights {
                    let d = pl.position - hit.point;
                    let dist = d.norm();
                    if dist <= 0.0 {
                        continue;
                    }
                    let wi_w = d / dist;
                    let wi = frame.to_local(&wi_w);
                    if wi.z <= 0.0 || !visible(rs, &hit, &wi_w, Some(&pl.position)) {
                        continue;
                    }
                    let s = wi.z / (dist * dist) * scale;
                    entries.push((merl_bin(&wi, &wo), pl.intensity.map(|i| (i * s) as f32)));
                }
            }
        }
    }
    if let Some(env) = &rs.scene.environment {
        let ns = opts.env_samples;
        let inv = 1.0 / ns as f64;
        let plan = match opts.env_sampling {
            EnvSampling::Independent => None,
            EnvSampling::Stratified => Some(stratified_plan(ns, mix, rng)),
        };
        // With a fixed count per proposal the balance heuristic's density uses the counts.
        let mix = match &plan {
            Some(p) => p.counts.map(|n| n as f64 * inv),
            None => mix,
        };
        for i in 0..ns {
            let (px, py, proposal, u1, u2) = match &plan {
                Some(p) => {
                    let s = p.samples[i];
                    (s[0], s[1], p.proposal[i], s[2], s[3])
                }
                None => {
                    let (px, py) = (uniform(rng), uniform(rng));
                    let pick = uniform(rng);
                    let proposal = if pick < mix[0] {
                        0
                    } else if pick < mix[0] + mix[1] {
                        1
                    } else {
                        2
                    };
                    (px, py, proposal, uniform(rng), uniform(rng))
                }
            };
            let ray = cam.ray(x as f64 + px, y as f64 + py);
            let Some((hit, frame, wo)) = trace(&ray) else {
                continue;
            };
            let wi_w = match proposal {
                0 => match env.sample_at(u1, u2) {
                    Some((d, _, _)) => d,
                    None => continue,
                },
                1 => frame.to_world(&cosine_hemisphere(u1, u2)),
                _ => frame.to_world(&sample_half(&wo, u1, u2)),
            };
            let wi = frame.to_local(&wi_w);
            if wi.z <= 0.0 {
                continue;
            }
            let pdf = mix[0] * env.pdf(&wi_w)
                + mix[1] * cosine_hemisphere_pdf(&wi)
                + mix[2] * half_pdf(&wi, &wo);
            if !(pdf > 0.0 && pdf.is_finite() && visible(rs, &hit, &wi_w, None)) {
                continue;
            }
            let le = env.radiance(&wi_w);
            let s = wi.z / pdf * inv;
            entries.push((merl_bin(&wi, &wo), le.map(|l| (l * s) as f32)));
        }
    }
    (all.then_some(entries).filter(|_| any), any)
}

/// The samples of one pixel under [`EnvSampling::Stratified`].
struct StratifiedPlan {
    /// Samples per proposal.
    counts: [usize; 3],
    /// Proposal of each sample.
    proposal: Vec<u8>,
    /// Sub-pixel position and the two direction uniforms of each sample.
    samples: Vec<[f64; 4]>,
}

/// Van der Corput radical inverse in base 2 of `i`.
fn radical_inverse_2(i: u32) -> f64 {
    i.reverse_bits() as f64 / 4_294_967_296.0
}

/// `n` points of the Hammersley set, shifted by a random vector modulo 1 (each point stays
/// uniform, the set keeps its stratification).
fn shifted_hammersley(n: usize, rng: &mut SampleRng) -> Vec<[f64; 2]> {
    let (s1, s2) = (uniform(rng), uniform(rng));
    (0..n)
        .map(|i| {
            let a = (i as f64 + 0.5) / n as f64 + s1;
            let b = radical_inverse_2(i as u32) + s2;
            [a - a.floor(), b - b.floor()]
        })
        .collect()
}

/// Counts per proposal by largest remainder, a Hammersley set of directions per proposal
/// and one of sub-pixel positions, the positions paired with the directions at random.
fn stratified_plan(n: usize, mix: [f64; 3], rng: &mut SampleRng) -> StratifiedPlan {
    let exact = mix.map(|m| m * n as f64);
    let mut counts = exact.map(|e| e.floor() as usize);
    let mut order = [0usize, 1, 2];
    order.sort_by(|&a, &b| (exact[b] - exact[b].floor()).total_cmp(&(exact[a] - exact[a].floor())));
    let mut k = 0;
    while counts.iter().sum::<usize>() < n {
        counts[order[k % 3]] += 1;
        k += 1;
    }
    let mut positions = shifted_hammersley(n, rng);
    // Fisher–Yates: the pairing of positions with directions is random.
    for i in (1..positions.len()).rev() {
        let j = ((uniform(rng) * (i + 1) as f64) as usize).min(i);
        positions.swap(i, j);
    }
    let mut proposal = Vec::with_capacity(n);
    let mut samples = Vec::with_capacity(n);
    for (j, &c) in counts.iter().enumerate() {
        for d in shifted_hammersley(c, rng) {
            let p = positions[samples.len()];
            proposal.push(j as u8);
            samples.push([p[0], p[1], d[0], d[1]]);
        }
    }
    StratifiedPlan {
        counts,
        proposal,
        samples,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The half-vector proposal's density, from its definition: `θh = u² π/2` with `u` and
    /// `φh` uniform, so `p(ωh) = 1 / (2π · π u · sin θh)` and `p(ωi) = p(ωh) / (4 ωo·h)`.
    fn density(th: f64, oh: f64) -> f64 {
        let u = (th / FRAC_PI_2).sqrt();
        1.0 / (2.0 * PI * PI * u * th.sin()) / (4.0 * oh)
    }

    #[test]
    fn half_vector_density_holds_next_to_the_specular_direction() {
        let wo = Vec3::new(0.3, 0.2, 0.9).normalize();
        for th in [1e-12f64, 1e-10, 1e-8, 1e-6, 1e-3, 0.3, 1.2] {
            let h = Vec3::new(th.sin() * 0.6, th.sin() * 0.8, th.cos());
            let wi = 2.0 * wo.dot(&h) * h - wo;
            let got = half_pdf(&wi, &wo);
            let want = density(th, wo.dot(&h));
            assert!(
                (got / want - 1.0).abs() < 1e-3,
                "θh = {th}: density {got}, expected {want}"
            );
        }
        // The proposal draws such directions: its own samples get its density back.
        for (u1, u2) in [(1e-5f64, 0.3), (0.2, 0.7), (0.9, 0.1)] {
            let wi = sample_half(&wo, u1, u2);
            let th = u1 * u1 * FRAC_PI_2;
            let h = (wi + wo).normalize();
            let want = density(th, wo.dot(&h));
            assert!((half_pdf(&wi, &wo) / want - 1.0).abs() < 1e-3, "u1 = {u1}");
        }
    }
}
