//! The real-time view's assets: the model's mean and components on a reduced grid in half
//! floats, the coefficients of a material, and the CPU reference image of the same scene.
//!
//! The page evaluates `f = max(exp(mean + Σ_j c_j · U_j) − floor, 0)` per fragment (thesis
//! §7.2.2: each point its own BRDF from a few coefficients against shared components). The
//! components go to the GPU as one 3-D texture; to fit, they are stored on a reduced
//! Rusinkiewicz grid ([`GpuGrid`]): each reduced bin is the mean of a block of the MERL
//! table's bins (in log space, where the model is linear). The default keeps θh's 90
//! square-root-spaced bins (the highlight lives there) and θd's 90 and averages φd over
//! blocks of 9 (20 bins over [0, π)): 162,000 bins of RGB half floats, 0.97 MB per component
//! against 17.5 MB for the full table in `f32`. φd is not folded onto [0, π/2]: isotropy
//! makes a BRDF symmetric about φd = π/2, but measured tables are not (the shared MERL
//! materials differ by a median 0.21 in log between mirrored bins for brass).
//! [`GpuBasis::eval`] is the shader's lookup on the CPU: the tests and
//! `cargo run -p serve --example gpu_error` measure what the reduction costs with it.

use crate::error::{Result, ServeError};
use brdf::HalfDiff;
use rayon::prelude::*;
use std::f64::consts::{FRAC_PI_2, PI};
use std::sync::Arc;

const MERL_TH: usize = 90;
const MERL_TD: usize = 90;
const MERL_PD: usize = 180;
const MERL_BINS: usize = MERL_TH * MERL_TD * MERL_PD;

/// Magic of the binary basis file the page reads (`/api/gpu/basis.bin`).
pub const GPU_BASIS_MAGIC: &[u8; 4] = b"GPUB";

/// A reduced Rusinkiewicz grid: bins over θh (square-root spaced, as MERL's), θd and φd
/// ∈ [0, π), each count a divisor of the MERL table's (90, 90, 180).
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize)]
pub struct GpuGrid {
    /// θh bins.
    pub theta_h: usize,
    /// θd bins.
    pub theta_d: usize,
    /// φd bins over [0, π).
    pub phi_d: usize,
}

impl Default for GpuGrid {
    /// 90 × 90 × 20: the choice of `gpu_error` over the shared materials (docs/serve.md).
    fn default() -> Self {
        GpuGrid {
            theta_h: 90,
            theta_d: 90,
            phi_d: 20,
        }
    }
}

impl GpuGrid {
    /// Checks that each count divides the MERL table's.
    pub fn validate(&self) -> Result<()> {
        let ok = |n: usize, of: usize| n > 0 && of.is_multiple_of(n);
        if ok(self.theta_h, MERL_TH) && ok(self.theta_d, MERL_TD) && ok(self.phi_d, MERL_PD) {
            Ok(())
        } else {
            Err(ServeError::InvalidParameter(format!(
                "reduced grid {}×{}×{}: each count must divide 90, 90 and 180",
                self.theta_h, self.theta_d, self.phi_d
            )))
        }
    }

    /// Number of bins.
    pub fn bins(&self) -> usize {
        self.theta_h * self.theta_d * self.phi_d
    }

    /// Continuous texel positions `(θh, θd, φd)` of a direction pair: texel `t` holds the
    /// value at position `t`; positions are clamped to the grid.
    ///
    /// A bin's value stands for its whole bin, as in the MERL table's lookup (nearest lower
    /// bin), so it sits at the bin's centre: `θd/(π/2) · n_d − ½` and `(φd mod π)/π · n_φ − ½`,
    /// interpolated between bins. On θh the bin is taken whole, `⌊√(θh/(π/2)) · n_h⌋`, as the
    /// table lookup does (interpolating across a metal's first θh bins loses 3–4 % of a
    /// chrome sphere's light against it); with `smooth_theta_h` it is interpolated too, at
    /// `√(θh/(π/2)) · n_h − ½`. These are texel centres, so a shader's hardware linear
    /// filtering computes the same interpolation.
    pub fn position(&self, hd: &HalfDiff, smooth_theta_h: bool) -> [f64; 3] {
        let th = hd.theta_h.clamp(0.0, FRAC_PI_2);
        let td = hd.theta_d.clamp(0.0, FRAC_PI_2);
        let pd = hd.phi_d.rem_euclid(PI);
        let at = |x: f64, n: usize| (x * n as f64 - 0.5).clamp(0.0, (n - 1) as f64);
        let u = (th / FRAC_PI_2).sqrt();
        [
            if smooth_theta_h {
                at(u, self.theta_h)
            } else {
                (u * self.theta_h as f64)
                    .floor()
                    .clamp(0.0, (self.theta_h - 1) as f64)
            },
            at(td / FRAC_PI_2, self.theta_d),
            at(pd / PI, self.phi_d),
        ]
    }
}

/// A model's mean and components on a reduced grid, as IEEE half floats.
///
/// Block `b` (0 = the mean, `j + 1` = component `j`) holds `grid.bins() × 3` values laid out
/// `[θh][θd][φd][rgb]` (φd fastest), the order of a 3-D texture upload with x = φd,
/// y = θd, z = θh.
#[derive(Debug, Clone)]
pub struct GpuBasis {
    grid: GpuGrid,
    components: usize,
    floor: f64,
    halves: Vec<u16>,
}

impl GpuBasis {
    /// Reduces the model's mean and all its components to `grid`.
    pub fn from_model(model: &reduce::Model, grid: GpuGrid) -> Result<GpuBasis> {
        grid.validate()?;
        let pca = &model.pca;
        let stored = pca.components;
        let n = 3 * MERL_BINS;
        if pca.mean.len() != n || pca.basis.len() != n * stored {
            return Err(ServeError::InvalidParameter(format!(
                "the real-time view needs a model on the MERL grid ({} values per vector), this one has {}",
                n,
                pca.mean.len()
            )));
        }
        let (fh, fd, fp) = (
            MERL_TH / grid.theta_h,
            MERL_TD / grid.theta_d,
            MERL_PD / grid.phi_d,
        );
        let count = (fh * fd * fp) as f64;
        let blocks = stored + 1;
        let block = grid.bins() * 3;
        let row_len = grid.theta_d * grid.phi_d * 3;
        // One θh row of the reduced grid per task: θd × φd × 3 values of every block.
        let rows: Vec<Vec<u16>> = (0..grid.theta_h)
            .into_par_iter()
            .map(|ih| {
                let mut out = vec![0u16; blocks * row_len];
                let mut acc = vec![0f64; blocks];
                for jd in 0..grid.theta_d {
                    for kd in 0..grid.phi_d {
                        for c in 0..3 {
                            acc.iter_mut().for_each(|a| *a = 0.0);
                            for i in ih * fh..(ih + 1) * fh {
                                for j in jd * fd..(jd + 1) * fd {
                                    for k in kd * fp..(kd + 1) * fp {
                                        let d = c * MERL_BINS + k + MERL_PD * (j + MERL_TD * i);
                                        acc[0] += pca.mean[d] as f64;
                                        let row = &pca.basis[d * stored..(d + 1) * stored];
                                        for (a, &v) in acc[1..].iter_mut().zip(row) {
                                            *a += v as f64;
                                        }
                                    }
                                }
                            }
                            let at = (jd * grid.phi_d + kd) * 3 + c;
                            for (b, a) in acc.iter().enumerate() {
                                out[b * row_len + at] = half::f16::from_f64(a / count).to_bits();
                            }
                        }
                    }
                }
                out
            })
            .collect();
        let mut halves = vec![0u16; blocks * block];
        for (i, row) in rows.iter().enumerate() {
            for b in 0..blocks {
                halves[b * block + i * row_len..][..row_len]
                    .copy_from_slice(&row[b * row_len..(b + 1) * row_len]);
            }
        }
        if halves.iter().any(|&h| !half::f16::from_bits(h).is_finite()) {
            return Err(ServeError::InvalidParameter(
                "the model's components overflow half floats".into(),
            ));
        }
        Ok(GpuBasis {
            grid,
            components: stored,
            floor: model.log_floor,
            halves,
        })
    }

    /// The reduced grid.
    pub fn grid(&self) -> GpuGrid {
        self.grid
    }

    /// Number of components held.
    pub fn components(&self) -> usize {
        self.components
    }

    /// The floor subtracted after the exponential.
    pub fn floor(&self) -> f64 {
        self.floor
    }

    /// Bytes of texture memory for the mean and `k` components.
    pub fn memory_bytes(&self, k: usize) -> usize {
        (k + 1) * self.grid.bins() * 3 * 2
    }

    /// The page's file of the mean and the first `k` components: `GPUB`, then little-endian
    /// `u32` version (1), θh, θd and φd bins, `k`, `f32` floor, then `k + 1` blocks of
    /// half floats (see [`GpuBasis`]).
    pub fn encode(&self, k: usize) -> Result<Vec<u8>> {
        if k > self.components {
            return Err(ServeError::InvalidParameter(format!(
                "k = {k}: the model has {} components",
                self.components
            )));
        }
        let values = (k + 1) * self.grid.bins() * 3;
        let mut out = Vec::with_capacity(28 + 2 * values);
        out.extend_from_slice(GPU_BASIS_MAGIC);
        for v in [1, self.grid.theta_h, self.grid.theta_d, self.grid.phi_d, k] {
            out.extend_from_slice(&(v as u32).to_le_bytes());
        }
        out.extend_from_slice(&(self.floor as f32).to_le_bytes());
        for h in &self.halves[..values] {
            out.extend_from_slice(&h.to_le_bytes());
        }
        Ok(out)
    }

    fn value(&self, block: usize, i: usize, j: usize, k: usize, c: usize) -> f64 {
        let g = &self.grid;
        let at = block * g.bins() * 3 + ((i * g.theta_d + j) * g.phi_d + k) * 3 + c;
        half::f16::from_bits(self.halves[at]).to_f64()
    }

    /// The BRDF the shader computes for these coefficients (only the first
    /// `coefficients.len()` components are used): trilinear interpolation of the reduced
    /// grid at [`GpuGrid::position`] (θh taken whole unless `smooth_theta_h`, the page's
    /// "smooth highlights"), `max(exp(y) − floor, 0)`.
    pub fn eval(&self, coefficients: &[f64], hd: &HalfDiff, smooth_theta_h: bool) -> [f64; 3] {
        let p = self.grid.position(hd, smooth_theta_h);
        let dims = [self.grid.theta_h, self.grid.theta_d, self.grid.phi_d];
        let mut corner = [[(0usize, 0f64); 2]; 3];
        for a in 0..3 {
            let f = p[a].floor().min((dims[a] - 1) as f64);
            let w = p[a] - f;
            let lo = f as usize;
            corner[a] = [(lo, 1.0 - w), ((lo + 1).min(dims[a] - 1), w)];
        }
        let m = coefficients.len().min(self.components);
        let mut out = [0.0; 3];
        for (c, o) in out.iter_mut().enumerate() {
            let mut y = 0.0;
            for &(i, wi) in &corner[0] {
                for &(j, wj) in &corner[1] {
                    for &(k, wk) in &corner[2] {
                        let wt = wi * wj * wk;
                        if wt == 0.0 {
                            continue;
                        }
                        let mut v = self.value(0, i, j, k, c);
                        for (b, &cb) in coefficients[..m].iter().enumerate() {
                            v += cb * self.value(b + 1, i, j, k, c);
                        }
                        y += wt * v;
                    }
                }
            }
            *o = (y.exp() - self.floor).max(0.0);
        }
        out
    }

    /// The reduced basis as a BRDF of given coefficients (for renders and error figures).
    pub fn brdf(self: &Arc<Self>, coefficients: &[f64]) -> GpuBrdf {
        GpuBrdf {
            basis: self.clone(),
            coefficients: coefficients.to_vec(),
        }
    }
}

/// A material evaluated exactly as the real-time view does by default ([`GpuBasis::eval`]).
#[derive(Debug, Clone)]
pub struct GpuBrdf {
    basis: Arc<GpuBasis>,
    coefficients: Vec<f64>,
}

impl brdf::Brdf for GpuBrdf {
    fn eval(&self, wi: &brdf::Vec3, wo: &brdf::Vec3) -> [f64; 3] {
        if wi.z <= 0.0 || wo.z <= 0.0 {
            return [0.0; 3];
        }
        self.eval_half_diff(&HalfDiff::from_directions(wi, wo))
    }

    fn eval_half_diff(&self, hd: &HalfDiff) -> [f64; 3] {
        self.basis.eval(&self.coefficients, hd, false)
    }

    fn name(&self) -> String {
        format!("real-time view ({} coefficients)", self.coefficients.len())
    }
}

/// What the reduced grid costs against the model's own reconstruction of the same
/// coefficients on the full grid, over every bin of the MERL table.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct GpuReductionError {
    /// Median over bins and channels where both are positive of |ln(f_gpu / f_full)|
    /// (`brdf::metrics::table_error`).
    pub median_abs_log: f64,
    /// Cosine-weighted relative RMS (`brdf::metrics::cosine_weighted_relative_rms`).
    pub cosine_weighted_relative_rms: f64,
}

/// Compares [`GpuBasis::eval`] with the full-grid reconstruction `model.synthesize(c)` at
/// the centre of every bin of the MERL table (the value a bin stands for).
pub fn gpu_reduction_error(
    model: &reduce::Model,
    basis: &GpuBasis,
    coefficients: &[f64],
) -> Result<GpuReductionError> {
    let full = model.synthesize(coefficients)?;
    let cells: Vec<[f64; 3]> = (0..MERL_BINS)
        .into_par_iter()
        .map(|b| {
            let (i, rest) = (b / (MERL_TD * MERL_PD), b % (MERL_TD * MERL_PD));
            let (j, k) = (rest / MERL_PD, rest % MERL_PD);
            let t = (i as f64 + 0.5) / MERL_TH as f64;
            let hd = HalfDiff {
                theta_h: t * t * FRAC_PI_2,
                phi_h: 0.0,
                theta_d: (j as f64 + 0.5) / MERL_TD as f64 * FRAC_PI_2,
                phi_d: (k as f64 + 0.5) / MERL_PD as f64 * PI,
            };
            basis.eval(coefficients, &hd, false)
        })
        .collect();
    let mut gpu = vec![0f64; full.len()];
    for (b, v) in cells.iter().enumerate() {
        for c in 0..3 {
            gpu[c * MERL_BINS + b] = v[c];
        }
    }
    let a = brdf::MerlTable::from_values(full)?;
    let b = brdf::MerlTable::from_values(gpu)?;
    Ok(GpuReductionError {
        median_abs_log: brdf::metrics::table_error(&b, &a).median_abs_log,
        cosine_weighted_relative_rms: brdf::metrics::cosine_weighted_relative_rms(&a, &b),
    })
}
