//! The non-linear least-squares fit of the PCA coefficients to the photographs.

use nalgebra::{DMatrix, DVector};
use rayon::prelude::*;

use crate::error::{RecoverError, Result};
use crate::functional::Functionals;
use crate::photo::Photo;

/// The PCA model restricted to the bins that the functionals touch.
#[derive(Debug, Clone)]
pub struct LocalModel {
    /// Number of coefficients.
    pub k: usize,
    /// Sorted MERL bins touched.
    pub bins: Vec<u32>,
    /// Log-space mean, `mean[c · S + s]`.
    pub mean: Vec<f32>,
    /// Basis, bin-major: `basis[(s · 3 + c) · k + j]` (the three channels of a bin side by
    /// side, so that one bin is one contiguous read).
    pub basis: Vec<f32>,
    /// Prior variance of each coefficient (`λ_j / (N − 1)`).
    pub prior_variance: Vec<f64>,
    /// Floor of the model's mapping (`ε` of `f = (exp(y) − ε) / w`).
    pub floor: f64,
    /// `1 / w` of each touched bin: the mapping's per-bin weight (the cosine product of the
    /// cosine-log mapping; 1 for the log mapping).
    pub inv_weight: Vec<f64>,
}

/// How many functional entries ahead the fit's inner loops prefetch.
const PREFETCH_AHEAD: usize = 4;

/// Asks the processor to bring the cache line of `p` in (a hint; nothing elsewhere).
#[inline(always)]
fn prefetch<T>(p: &T) {
    #[cfg(target_arch = "x86_64")]
    // SAFETY: a prefetch is a hint that never faults, and `p` is a valid reference.
    unsafe {
        std::arch::x86_64::_mm_prefetch::<{ std::arch::x86_64::_MM_HINT_T0 }>(
            (p as *const T).cast::<i8>(),
        )
    };
    #[cfg(not(target_arch = "x86_64"))]
    let _ = p;
}

/// Checks that a model is a full-grid MERL model (in any mapping).
pub fn check_model_grid(model: &reduce::Model) -> Result<()> {
    let expected = 3 * brdf::BINS;
    if model.pca.dim != expected {
        return Err(RecoverError::ModelGrid {
            expected,
            got: model.pca.dim,
        });
    }
    Ok(())
}

impl LocalModel {
    /// Restricts `model` (first `k` components) to the bins touched by `functionals`.
    pub fn new(model: &reduce::Model, k: usize, functionals: &[&Functionals]) -> Result<Self> {
        check_model_grid(model)?;
        if k == 0 || k > model.components() {
            return Err(RecoverError::InvalidParameter(format!(
                "k = {k} but the model has {} components",
                model.components()
            )));
        }
        let mut bins: Vec<u32> = functionals
            .iter()
            .flat_map(|f| f.bins.iter().copied())
            .collect();
        bins.par_sort_unstable();
        bins.dedup();
        let s = bins.len();
        let kk = model.components();
        let nb = brdf::BINS;
        let mut mean = vec![0.0f32; 3 * s];
        for c in 0..3 {
            for (i, &b) in bins.iter().enumerate() {
                mean[c * s + i] = model.pca.mean[c * nb + b as usize];
            }
        }
        let mut basis = vec![0.0f32; 3 * s * k];
        basis
            .par_chunks_mut(3 * k)
            .zip(&bins)
            .for_each(|(block, &b)| {
                for (c, u) in block.chunks_exact_mut(k).enumerate() {
                    let d = c * nb + b as usize;
                    u.copy_from_slice(&model.pca.basis[d * kk..d * kk + k]);
                }
            });
        let n = model.names.len().max(2) as f64;
        let prior_variance = model.pca.eigenvalues[..k]
            .iter()
            .map(|&l| (l / (n - 1.0)).max(1e-12))
            .collect();
        let (floor, weights) = model.mapping.inverse_form();
        let inv_weight = bins
            .iter()
            .map(|&b| weights.map_or(1.0, |w| 1.0 / w[b as usize] as f64))
            .collect();
        Ok(LocalModel {
            k,
            bins,
            mean,
            basis,
            prior_variance,
            floor,
            inv_weight,
        })
    }

    /// Number of touched bins.
    pub fn len(&self) -> usize {
        self.bins.len()
    }

    /// Whether no bin is touched.
    pub fn is_empty(&self) -> bool {
        self.bins.is_empty()
    }

    /// `exp(y) / w` at every touched bin and channel for coefficients `x`: the derivative of
    /// the BRDF value with respect to the model-space value `y`, `[c · S + s]`.
    pub fn exp_log(&self, x: &[f64]) -> Vec<f64> {
        let by_bin = self.exp_log_by_bin(x);
        (0..3)
            .flat_map(|c| by_bin.iter().map(move |e| e[c]))
            .collect()
    }

    /// [`LocalModel::exp_log`] bin-major, `[s][c]`: the three channels of a bin side by side
    /// for the fit's scattered reads.
    pub(crate) fn exp_log_by_bin(&self, x: &[f64]) -> Vec<[f64; 3]> {
        let k = self.k;
        let sz = self.len();
        let xf: Vec<f32> = x.iter().map(|&v| v as f32).collect();
        (0..sz)
            .into_par_iter()
            .map(|b| {
                let block = &self.basis[b * 3 * k..(b + 1) * 3 * k];
                let mut out = [0.0; 3];
                for (c, o) in out.iter_mut().enumerate() {
                    let s = self.mean[c * sz + b] + reduce::dot(&block[c * k..(c + 1) * k], &xf);
                    // `s` is single precision: so is its exponential, at no loss. Past f32's
                    // range (exp(88.7), absurd for a BRDF) it is infinite, and the fit
                    // rejects the step that led there as it rejects any non-finite cost.
                    *o = s.exp() as f64 * self.inv_weight[b];
                }
                out
            })
            .collect()
    }

    /// `floor / w` of entry `i` (`[c · S + s]`): with [`LocalModel::exp_log`], the value is
    /// `exp_log − offset`.
    pub fn offset(&self, i: usize) -> f64 {
        self.floor * self.inv_weight[i % self.len()]
    }

    /// BRDF values at the touched bins (`(exp(y) − floor) / w`, clamped to ≥ 0), `[c · S + s]`.
    pub fn values(&self, x: &[f64]) -> Vec<f64> {
        self.exp_log(x)
            .into_iter()
            .enumerate()
            .map(|(i, e)| (e - self.offset(i)).max(0.0))
            .collect()
    }

    /// Local index of a MERL bin.
    pub fn local(&self, bin: u32) -> Option<usize> {
        self.bins.binary_search(&bin).ok()
    }
}

/// One photograph with its functionals, the data term of the fit.
#[derive(Debug, Clone)]
pub struct Observation {
    /// The pixel functionals.
    pub functionals: Functionals,
    /// Observed radiance of each row.
    pub observed: Vec<[f64; 3]>,
    /// Whether each row and channel is used (not saturated, not masked).
    pub usable: Vec<[bool; 3]>,
}

/// The largest median ratio of observed radiance to a white diffuse surface's that
/// [`Observation::checked`] accepts. Measured materials reflect at most about their albedo
/// (≤ 1) times the white surface's radiance away from highlights, so a median above this is a
/// photograph exposed for other lights.
pub const MAX_WHITE_RATIO: f64 = 10.0;

impl Observation {
    /// Pairs functionals with photograph number `index` and checks it: its size must be the
    /// camera's, some object pixels must be unsaturated and lit, and (without an environment
    /// map, whose background shows) the light must fall on the object, not beside it.
    pub fn checked(
        index: usize,
        functionals: Functionals,
        photo: &Photo,
        mask: Option<&[bool]>,
        background_is_dark: bool,
    ) -> Result<Self> {
        if photo.width != functionals.width || photo.height != functionals.height {
            return Err(RecoverError::CameraMismatch {
                index,
                width: functionals.width,
                height: functionals.height,
                got_width: photo.width,
                got_height: photo.height,
            });
        }
        if let Some(m) = mask {
            if m.len() != photo.pixels.len() {
                return Err(RecoverError::MaskMismatch {
                    width: photo.width,
                    height: photo.height,
                    got_width: m.len(),
                    got_height: 1,
                });
            }
        }
        if functionals.is_empty() {
            return Err(RecoverError::Scene(format!(
                "the camera of image {index} sees no pixel of the unknown material"
            )));
        }
        let object = functionals.len();
        // Rows the lights reach: a pixel in shadow carries no information whatever its value.
        let white = functionals.white_response();
        let lit_rows: Vec<usize> = (0..object)
            .filter(|&r| white[r].iter().sum::<f64>() > 0.0)
            .collect();
        let is_saturated = |r: usize| photo.saturated(functionals.pixels[r] as usize);
        let saturated = lit_rows.iter().filter(|&&r| is_saturated(r)).count();
        if !lit_rows.is_empty() && saturated == lit_rows.len() {
            return Err(RecoverError::AllSaturated {
                index,
                saturated,
                object: lit_rows.len(),
                level: photo.saturation.unwrap_or(f32::INFINITY),
            });
        }
        let lum = |p: &[f32; 3]| (p[0] + p[1] + p[2]) as f64 / 3.0;
        let peak = photo
            .pixels
            .iter()
            .map(lum)
            .filter(|v| v.is_finite())
            .fold(0.0, f64::max);
        if background_is_dark {
            let (mut on, mut off) = (0.0, 0.0);
            for (i, p) in photo.pixels.iter().enumerate() {
                let v = lum(p);
                if !v.is_finite() {
                    continue;
                }
                if functionals.coverage[i] {
                    on += v;
                } else {
                    off += v;
                }
            }
            if off > on {
                return Err(RecoverError::Silhouette {
                    index,
                    message: format!(
                        "{:.0} % of the light is outside the object's silhouette",
                        100.0 * off / (on + off)
                    ),
                });
            }
        }
        let lit = functionals
            .pixels
            .iter()
            .filter(|&&p| lum(&photo.pixels[p as usize]) > 1e-4 * peak.max(1e-30))
            .count();
        if peak <= 0.0 || lit * 100 < object {
            return Err(RecoverError::AllDark {
                index,
                message: format!("{lit} of {object} object pixels have any light"),
            });
        }
        let mut ratios: Vec<f64> = lit_rows
            .iter()
            .filter(|&&r| !is_saturated(r))
            .filter_map(|&r| {
                let seen = lum(&photo.pixels[functionals.pixels[r] as usize]);
                let w = white[r].iter().sum::<f64>() / 3.0;
                (seen.is_finite() && w > 0.0).then_some(seen / w)
            })
            .collect();
        if !ratios.is_empty() {
            let mid = ratios.len() / 2;
            let ratio = *ratios.select_nth_unstable_by(mid, f64::total_cmp).1;
            if ratio > MAX_WHITE_RATIO {
                return Err(RecoverError::Overexposed {
                    index,
                    ratio,
                    limit: MAX_WHITE_RATIO,
                });
            }
        }
        Self::new(functionals, photo, mask)
    }

    /// Per MERL bin, whether a usable row channel of some observation gives it a non-zero
    /// weight: the bins the photographs constrain. The rest are fixed by the model alone;
    /// errors over the two regions ([`brdf::metrics::cosine_weighted_relative_rms_where`])
    /// say where a recovery's error lives.
    pub fn constrained_bins(observations: &[Observation]) -> Vec<bool> {
        let mut seen = vec![false; brdf::BINS];
        for o in observations {
            let f = &o.functionals;
            for (r, u) in o.usable.iter().enumerate() {
                for e in f.row_ptr[r]..f.row_ptr[r + 1] {
                    if (0..3).any(|c| u[c] && f.weights[e][c] != 0.0) {
                        seen[f.bins[e] as usize] = true;
                    }
                }
            }
        }
        seen
    }

    /// Rows the fit uses: some channel usable, and light reaching the pixel.
    pub fn fitted_pixels(&self) -> usize {
        let white = self.functionals.white_response();
        self.usable
            .iter()
            .zip(&white)
            .filter(|(u, w)| u.iter().any(|&b| b) && w.iter().sum::<f64>() > 0.0)
            .count()
    }

    /// Every `step`-th row (all rows for `step` ≤ 1).
    pub fn every(&self, step: usize) -> Observation {
        let step = step.max(1);
        Observation {
            functionals: self.functionals.subset(|r| r % step == 0),
            observed: self.observed.iter().copied().step_by(step).collect(),
            usable: self.usable.iter().copied().step_by(step).collect(),
        }
    }

    /// Pairs functionals with a photograph and an optional mask (false = left out), checking
    /// only the size.
    pub fn new(functionals: Functionals, photo: &Photo, mask: Option<&[bool]>) -> Result<Self> {
        if photo.width != functionals.width || photo.height != functionals.height {
            return Err(RecoverError::CameraMismatch {
                index: 0,
                width: functionals.width,
                height: functionals.height,
                got_width: photo.width,
                got_height: photo.height,
            });
        }
        let mut observed = Vec::with_capacity(functionals.len());
        let mut usable = Vec::with_capacity(functionals.len());
        for &p in &functionals.pixels {
            let p = p as usize;
            let v = photo.pixels[p];
            let keep = mask.is_none_or(|m| m[p]) && !photo.saturated(p);
            observed.push(v.map(|x| x as f64));
            usable.push(v.map(|x| keep && x.is_finite() && x >= 0.0));
        }
        Ok(Observation {
            functionals,
            observed,
            usable,
        })
    }
}

/// Fit settings.
#[derive(Debug, Clone, PartialEq)]
pub struct FitOptions {
    /// Weight `τ` of the corpus prior (0 = none).
    pub prior_weight: f64,
    /// Weight `ω` of the prior on the log table in the bins the photographs do not see
    /// ([`TablePrior`]; 0 = none).
    pub table_prior: f64,
    /// Huber threshold in units of the robust residual scale.
    pub huber: f64,
    /// `ε` as a fraction of each channel's mean observed radiance.
    pub epsilon_fraction: f64,
    /// Maximum Levenberg–Marquardt iterations.
    pub max_iterations: usize,
    /// Stop when the relative decrease of the objective is below this.
    pub tolerance: f64,
}

impl Default for FitOptions {
    fn default() -> Self {
        FitOptions {
            prior_weight: 1.0,
            table_prior: 0.0,
            huber: 1.345,
            epsilon_fraction: 0.01,
            max_iterations: 25,
            tolerance: 1e-7,
        }
    }
}

/// The fitted coefficients and their diagnostics.
#[derive(Debug, Clone, PartialEq)]
pub struct Fit {
    /// PCA coefficients.
    pub coefficients: Vec<f64>,
    /// Nominal standard deviation of each coefficient.
    pub uncertainty: Vec<f64>,
    /// Final objective.
    pub objective: f64,
    /// Robust residual scale `σ` (log radiance).
    pub sigma: f64,
    /// RMS log residual of each observation.
    pub residual_rms: Vec<f64>,
    /// Iterations taken.
    pub iterations: usize,
}

/// A fitting problem: observations against a local model. Rows can be restricted to a subset
/// (cross-validation folds).
///
/// With `x` the first `k` PCA coordinates, the model-space table is `y = m + U x` and the BRDF
/// value of bin `b`, channel `c`, is `f = (exp(y) − floor) / a_b` (the model's mapping
/// inverted, [`reduce::Mapping::inverse_form`]: `a_b = 1` for the thesis's log mapping, the
/// bin's cosine product for the cosine-log one). Each usable pixel channel gives the residual
/// `r = ln(Î + ε) − ln(I + ε)` between the predicted `Î = Σ_b w_b f_b` and the observed
/// radiance `I` (`ε` a small fraction of the channel's mean radiance), so bright highlights
/// and dark flanks count alike. The Jacobian is analytic:
/// `∂Î/∂x_k = Σ_b w_b exp(y_b) U_{b,k} / a_b`.
///
/// The objective is `Σ ρ_H(r) + ½ τ σ² xᵀ Λ⁻¹ x`: the Huber loss `ρ_H` (threshold `δ σ`, with
/// `σ` the robust scale of the residuals, 1.4826 × MAD) keeps outlier pixels from dominating,
/// and the Gaussian prior with the corpus coordinate variances `Λ = diag(λ_k / (N − 1))`
/// (the PCA coordinates of the corpus are uncorrelated) keeps poorly observed directions
/// near the corpus. Levenberg–Marquardt with iteratively reweighted normal equations solves
/// it. The nominal posterior covariance is `(JᵀWJ / σ² + τ Λ⁻¹)⁻¹`.
///
/// # Examples
///
/// ```
/// use recover::{FitOptions, LocalModel, Problem};
/// # use recover::{FunctionalOptions, Functionals, Observation, Photo, RecoveryScene};
/// // Four analytic materials on the MERL grid and the 3-component PCA model of them.
/// let specs = ["lambert:kd=0.7", "lambert:kd=0.2/0.3/0.6", "ggx:alpha=0.2,kd=0.1", "ggx:alpha=0.4,kd=0.4"];
/// let tables: Vec<brdf::MerlTable> = specs.iter().map(|s| brdf::load(s).unwrap().tabulate()).collect();
/// let mut corpus = reduce::Corpus::new(reduce::MATERIAL_DIM);
/// for (s, t) in specs.iter().zip(&tables) {
///     corpus.push_values(s.to_string(), &t.values()).unwrap();
/// }
/// let model = reduce::build_model(&corpus, 3, None, None).unwrap();
/// // A 24 × 24 view of a unit sphere under one point light, "photographed" in the third
/// // material: every pixel's radiance is its functional applied to the true table.
/// let light = RecoveryScene::point_light_toml([2.0, 2.0, 4.0], 25.0);
/// let scene = RecoveryScene::unit_sphere(24, &light).unwrap();
/// let functionals = Functionals::build(&scene, &FunctionalOptions::default()).unwrap();
/// let mut pixels = vec![[0.0f32; 3]; 24 * 24];
/// for (&p, v) in functionals.pixels.iter().zip(functionals.apply_table(&tables[2])) {
///     pixels[p as usize] = v.map(|x| x as f32);
/// }
/// let photo = Photo::new(24, 24, pixels).unwrap();
/// let observations = vec![Observation::new(functionals, &photo, None).unwrap()];
/// let local = LocalModel::new(&model, 3, &[&observations[0].functionals]).unwrap();
/// let opts = FitOptions::default();
/// let problem = Problem::new(&local, &observations, &opts).unwrap();
/// // The true material's own coordinates explain the photograph exactly.
/// let truth: Vec<f64> = model.pca.coords.row(2).iter().copied().collect();
/// assert!(problem.residual_rms(&truth)[0] < 1e-3);
/// // The fit, started at the corpus mean, finds them.
/// let fit = problem.fit(&[0.0; 3], &opts).unwrap();
/// assert!(fit.residual_rms[0] < 0.01, "{:?}", fit.residual_rms);
/// assert_eq!(fit.uncertainty.len(), 3);
/// ```
#[derive(Debug, Clone)]
pub struct Problem<'a> {
    model: &'a LocalModel,
    obs: &'a [Observation],
    /// Local bin index of every entry, per observation.
    local: Vec<Vec<u32>>,
    /// `ε` per channel, per observation.
    eps: Vec<[f64; 3]>,
    /// Row filter per observation (`None` = all rows).
    filter: Option<Vec<Vec<bool>>>,
    /// Precision of the table prior on the coefficients (`k × k`), if any.
    table_precision: Option<DMatrix<f64>>,
}

/// Partial `JᵀWJ`, `JᵀWr` and residuals of a chunk of rows.
type ChunkNormal = (DMatrix<f64>, DVector<f64>, Vec<f64>);

/// Normal equations of one evaluation.
/// `ε` per channel of an observation: `fraction` of the channel's mean usable radiance.
pub(crate) fn channel_epsilon(o: &Observation, fraction: f64) -> [f64; 3] {
    let mut e = [0.0; 3];
    for c in 0..3 {
        let (mut s, mut n) = (0.0, 0usize);
        for (v, u) in o.observed.iter().zip(&o.usable) {
            if u[c] {
                s += v[c];
                n += 1;
            }
        }
        e[c] = (fraction * s / n.max(1) as f64).max(1e-12);
    }
    e
}

struct Normal {
    h: DMatrix<f64>,
    g: DVector<f64>,
}

fn huber(r: f64, c: f64) -> (f64, f64) {
    let a = r.abs();
    if a <= c {
        (0.5 * r * r, 1.0)
    } else {
        (c * a - 0.5 * c * c, c / a)
    }
}

impl<'a> Problem<'a> {
    /// A problem over all usable rows.
    pub fn new(model: &'a LocalModel, obs: &'a [Observation], opts: &FitOptions) -> Result<Self> {
        let mut local = Vec::new();
        let mut eps = Vec::new();
        for o in obs {
            let l: Option<Vec<u32>> = o
                .functionals
                .bins
                .iter()
                .map(|&b| model.local(b).map(|i| i as u32))
                .collect();
            local.push(l.ok_or_else(|| {
                RecoverError::InvalidParameter("model does not cover the observations' bins".into())
            })?);
            eps.push(channel_epsilon(o, opts.epsilon_fraction));
        }
        Ok(Problem {
            model,
            obs,
            local,
            eps,
            filter: None,
            table_precision: None,
        })
    }

    /// The observations.
    pub fn observations(&self) -> &[Observation] {
        self.obs
    }

    /// The same problem on a subset of rows.
    pub fn with_filter(mut self, filter: Vec<Vec<bool>>) -> Self {
        self.filter = Some(filter);
        self
    }

    /// The same problem with a prior on the table in unobserved bins (weighted by
    /// [`FitOptions::table_prior`]).
    pub fn with_table_prior(mut self, prior: &TablePrior) -> Self {
        self.table_precision = Some(prior.precision.clone());
        self
    }

    fn row_used(&self, o: usize, r: usize) -> bool {
        self.filter.as_ref().is_none_or(|f| f[o][r])
    }

    /// Predicted radiance of every row of every observation.
    pub fn predict(&self, x: &[f64]) -> Vec<Vec<[f64; 3]>> {
        let e = self.model.exp_log_by_bin(x);
        self.predict_from(&e)
    }

    fn predict_from(&self, e: &[[f64; 3]]) -> Vec<Vec<[f64; 3]>> {
        self.obs
            .iter()
            .zip(&self.local)
            .map(|(o, loc)| {
                let f = &o.functionals;
                (0..f.len())
                    .into_par_iter()
                    .map(|r| {
                        let mut acc = [0.0; 3];
                        let (start, end) = (f.row_ptr[r], f.row_ptr[r + 1]);
                        for i in start..end {
                            if i + PREFETCH_AHEAD < end {
                                prefetch(&e[loc[i + PREFETCH_AHEAD] as usize]);
                            }
                            let l = loc[i] as usize;
                            let off = self.model.offset(l);
                            for c in 0..3 {
                                acc[c] += f.weights[i][c] as f64 * (e[l][c] - off);
                            }
                        }
                        acc
                    })
                    .collect()
            })
            .collect()
    }

    /// Calls `f(observation, log residual)` for every usable row channel of `pred`, in the
    /// flattened order of [`Problem::residuals`].
    fn for_each_log_residual(&self, pred: &[Vec<[f64; 3]>], mut f: impl FnMut(usize, f64)) {
        for (oi, o) in self.obs.iter().enumerate() {
            for r in 0..o.observed.len() {
                if !self.row_used(oi, r) {
                    continue;
                }
                for c in 0..3 {
                    if o.usable[r][c] {
                        let ep = self.eps[oi][c];
                        f(
                            oi,
                            (pred[oi][r][c].max(0.0) + ep).ln() - (o.observed[r][c] + ep).ln(),
                        );
                    }
                }
            }
        }
    }

    /// Log residuals of every usable row channel (flattened) at `x`.
    pub fn residuals(&self, x: &[f64]) -> Vec<f64> {
        let pred = self.predict(x);
        let mut out = Vec::new();
        self.for_each_log_residual(&pred, |_, d| out.push(d));
        out
    }

    /// RMS log residual per observation at `x`.
    pub fn residual_rms(&self, x: &[f64]) -> Vec<f64> {
        let pred = self.predict(x);
        self.rms_of(&pred)
    }

    /// RMS log residual per observation of given predictions.
    pub fn rms_of(&self, pred: &[Vec<[f64; 3]>]) -> Vec<f64> {
        let mut sums = vec![(0.0, 0usize); self.obs.len()];
        self.for_each_log_residual(pred, |oi, d| {
            sums[oi].0 += d * d;
            sums[oi].1 += 1;
        });
        sums.into_iter()
            .map(|(s, n)| (s / n.max(1) as f64).sqrt())
            .collect()
    }

    /// Robust data cost `Σ ρ_H(r)` (threshold `c`) of given predictions.
    pub fn robust_cost_of(&self, pred: &[Vec<[f64; 3]>], c: f64) -> f64 {
        let mut cost = 0.0;
        self.for_each_log_residual(pred, |_, d| cost += huber(d, c).0);
        cost
    }

    /// Jacobian rows `∂r/∂x` of every usable row channel at `x` (flattened like
    /// [`Problem::residuals`]), `len × k` row-major.
    pub fn jacobian(&self, x: &[f64]) -> Vec<f64> {
        let k = self.model.k;
        let e = self.model.exp_log_by_bin(x);
        let pred = self.predict_from(&e);
        let mut out = Vec::new();
        let mut j = vec![0.0f32; 3 * k];
        for (oi, o) in self.obs.iter().enumerate() {
            for r in 0..o.observed.len() {
                if !self.row_used(oi, r) {
                    continue;
                }
                self.row_jacobian(oi, r, &e, &mut j);
                for c in 0..3 {
                    if o.usable[r][c] {
                        let p = pred[oi][r][c];
                        let d = if p > 0.0 {
                            1.0 / (p + self.eps[oi][c])
                        } else {
                            0.0
                        };
                        out.extend(j[c * k..(c + 1) * k].iter().map(|&v| v as f64 * d));
                    }
                }
            }
        }
        out
    }

    /// `∂Î_c/∂x` of one row, `[c · k + j]`, written to `j` (length `3k`). Summed in single
    /// precision (the basis's own): the Jacobian steers the steps, the objective that accepts
    /// them is summed in double.
    fn row_jacobian(&self, oi: usize, r: usize, e: &[[f64; 3]], j: &mut [f32]) {
        let k = self.model.k;
        let f = &self.obs[oi].functionals;
        let loc = &self.local[oi];
        j.fill(0.0);
        let (start, end) = (f.row_ptr[r], f.row_ptr[r + 1]);
        for i in start..end {
            if i + PREFETCH_AHEAD < end {
                // The bins of a row are scattered over the table: ask for the block a few
                // entries ahead so that its cache misses overlap this entry's work.
                let l = loc[i + PREFETCH_AHEAD] as usize;
                prefetch(&e[l]);
                for line in (l * 3 * k..(l + 1) * 3 * k).step_by(16) {
                    prefetch(&self.model.basis[line]);
                }
            }
            let l = loc[i] as usize;
            let block = &self.model.basis[l * 3 * k..(l + 1) * 3 * k];
            for c in 0..3 {
                let g = (f.weights[i][c] as f64 * e[l][c]) as f32;
                let u = &block[c * k..(c + 1) * k];
                for (a, b) in j[c * k..(c + 1) * k].iter_mut().zip(u) {
                    *a += g * *b;
                }
            }
        }
    }

    /// Weighted normal equations `JᵀWJ`, `JᵀWr` and the robust cost at `x`.
    fn normal(&self, x: &[f64], c: f64) -> (Normal, Vec<f64>) {
        let k = self.model.k;
        let e = self.model.exp_log_by_bin(x);
        let pred = self.predict_from(&e);
        let mut h = DMatrix::zeros(k, k);
        let mut g = DVector::zeros(k);
        let mut resid = Vec::new();
        for (oi, o) in self.obs.iter().enumerate() {
            let parts: Vec<ChunkNormal> = (0..o.observed.len())
                .into_par_iter()
                .chunks(512)
                .map(|rows| {
                    // Each usable row channel is a column `√w ∂r/∂x` of `B` and an entry
                    // `√w r` of `q`: the chunk adds `B Bᵀ` and `B q` (one matrix product
                    // instead of a rank-one update per residual).
                    let mut cols = Vec::with_capacity(3 * rows.len() * k);
                    let mut q = Vec::with_capacity(3 * rows.len());
                    let mut rr = Vec::new();
                    let mut j = vec![0.0f32; 3 * k];
                    for r in rows {
                        if !self.row_used(oi, r) {
                            continue;
                        }
                        self.row_jacobian(oi, r, &e, &mut j);
                        for ch in 0..3 {
                            if !o.usable[r][ch] {
                                continue;
                            }
                            let ep = self.eps[oi][ch];
                            let p = pred[oi][r][ch];
                            let res = (p.max(0.0) + ep).ln() - (o.observed[r][ch] + ep).ln();
                            rr.push(res);
                            if p <= 0.0 {
                                continue;
                            }
                            let sw = huber(res, c).1.sqrt();
                            let d = sw / (p + ep);
                            cols.extend(j[ch * k..(ch + 1) * k].iter().map(|&v| v as f64 * d));
                            q.push(sw * res);
                        }
                    }
                    let n = q.len();
                    let b = DMatrix::from_vec(k, n, cols);
                    let mut hh = DMatrix::zeros(k, k);
                    hh.gemm(1.0, &b, &b.transpose(), 0.0);
                    let gg = &b * DVector::from_vec(q);
                    (hh, gg, rr)
                })
                .collect();
            for (hh, gg, rr) in parts {
                h += hh;
                g += gg;
                resid.extend(rr);
            }
        }
        (Normal { h, g }, resid)
    }

    /// Number of residuals (usable row channels) in the problem.
    pub fn residual_count(&self) -> usize {
        let mut n = 0;
        for (oi, o) in self.obs.iter().enumerate() {
            for (r, u) in o.usable.iter().enumerate() {
                if self.row_used(oi, r) {
                    n += u.iter().filter(|&&b| b).count();
                }
            }
        }
        n
    }

    /// `τ n / 1000`: the prior weight per thousand residuals, times their number.
    fn prior_scale(&self, opts: &FitOptions) -> f64 {
        opts.prior_weight * self.residual_count() as f64 / 1000.0
    }

    /// `ω n / 1000`, the table prior's weight (0 without a table prior).
    fn table_scale(&self, opts: &FitOptions) -> f64 {
        if self.table_precision.is_some() {
            opts.table_prior * self.residual_count() as f64 / 1000.0
        } else {
            0.0
        }
    }

    /// Prior cost with the coefficient prior weighted by `tau_s2` and the table prior by
    /// `omega_s2`.
    fn prior_cost(&self, x: &[f64], tau_s2: f64, omega_s2: f64) -> f64 {
        let mut c = 0.5
            * tau_s2
            * x.iter()
                .zip(&self.model.prior_variance)
                .map(|(v, p)| v * v / p)
                .sum::<f64>();
        if let Some(p) = &self.table_precision {
            if omega_s2 > 0.0 {
                let xv = DVector::from_column_slice(x);
                c += 0.5 * omega_s2 * xv.dot(&(p * &xv));
            }
        }
        c
    }

    /// Adds the priors' Hessian (and, with `g`, gradient at `x`) to the normal equations.
    fn add_priors(
        &self,
        h: &mut DMatrix<f64>,
        g: Option<&mut DVector<f64>>,
        x: &[f64],
        tau_s2: f64,
        omega_s2: f64,
    ) {
        let k = self.model.k;
        for a in 0..k {
            h[(a, a)] += tau_s2 / self.model.prior_variance[a];
        }
        let table = self.table_precision.as_ref().filter(|_| omega_s2 > 0.0);
        if let Some(p) = table {
            *h += p * omega_s2;
        }
        if let Some(g) = g {
            for a in 0..k {
                g[a] += tau_s2 * x[a] / self.model.prior_variance[a];
            }
            if let Some(p) = table {
                *g += (p * DVector::from_column_slice(x)) * omega_s2;
            }
        }
    }

    /// Levenberg–Marquardt from `start` (length ≤ k, padded with zeros).
    pub fn fit(&self, start: &[f64], opts: &FitOptions) -> Result<Fit> {
        let k = self.model.k;
        let mut x = vec![0.0; k];
        for (a, b) in x.iter_mut().zip(start) {
            *a = *b;
        }
        let mut sigma = robust_scale(&self.residuals(&x));
        let mut mu = 1e-3;
        let mut iterations = 0;
        let mut last = None;
        for it in 0..opts.max_iterations {
            iterations = it + 1;
            let c = opts.huber * sigma;
            let (n, resid) = self.normal(&x, c);
            if it < 6 {
                sigma = robust_scale(&resid);
            }
            let c = opts.huber * sigma;
            let tau_s2 = self.prior_scale(opts) * sigma * sigma;
            let omega_s2 = self.table_scale(opts) * sigma * sigma;
            // The residuals at `x` came with the normal equations: no second prediction.
            let cost = resid.iter().map(|&r| huber(r, c).0).sum::<f64>()
                + self.prior_cost(&x, tau_s2, omega_s2);
            let mut h = n.h.clone();
            let mut g = n.g.clone();
            self.add_priors(&mut h, Some(&mut g), &x, tau_s2, omega_s2);
            let mut accepted = false;
            for _ in 0..8 {
                let mut hd = h.clone();
                for a in 0..k {
                    hd[(a, a)] += mu * h[(a, a)].max(1e-12);
                }
                let Some(ch) = hd.cholesky() else {
                    mu *= 10.0;
                    continue;
                };
                let step = ch.solve(&(-&g));
                let xn: Vec<f64> = x.iter().zip(step.iter()).map(|(a, b)| a + b).collect();
                if xn.iter().any(|v| !v.is_finite()) {
                    mu *= 10.0;
                    continue;
                }
                let cn = self.robust_cost_of(&self.predict(&xn), c)
                    + self.prior_cost(&xn, tau_s2, omega_s2);
                if cn < cost {
                    let rel = (cost - cn) / cost.max(1e-300);
                    x = xn;
                    mu = (mu / 3.0).max(1e-9);
                    accepted = true;
                    last = Some(cn);
                    if rel < opts.tolerance {
                        return self.finish(x, sigma, opts, iterations);
                    }
                    break;
                }
                mu *= 4.0;
            }
            if !accepted {
                break;
            }
        }
        let _ = last;
        self.finish(x, sigma, opts, iterations)
    }

    fn finish(&self, x: Vec<f64>, sigma: f64, opts: &FitOptions, iterations: usize) -> Result<Fit> {
        let k = self.model.k;
        let c = opts.huber * sigma;
        let (n, _) = self.normal(&x, c);
        let s2 = sigma * sigma;
        let tau = self.prior_scale(opts);
        let omega = self.table_scale(opts);
        let mut h = n.h / s2.max(1e-300);
        self.add_priors(&mut h, None, &x, tau, omega);
        let uncertainty = match h.clone().cholesky() {
            Some(ch) => {
                let inv = ch.inverse();
                (0..k).map(|a| inv[(a, a)].max(0.0).sqrt()).collect()
            }
            None => vec![f64::INFINITY; k],
        };
        let pred = self.predict(&x);
        let objective = self.robust_cost_of(&pred, c) + self.prior_cost(&x, tau * s2, omega * s2);
        if !objective.is_finite() {
            return Err(RecoverError::Fit("non-finite objective".into()));
        }
        Ok(Fit {
            residual_rms: self.rms_of(&pred),
            coefficients: x,
            uncertainty,
            objective,
            sigma,
            iterations,
        })
    }
}

/// A Gaussian prior on the log table in the bins the photographs do not see, as a precision
/// on the coefficients.
///
/// In bin `b` (channel and MERL bin) the model's log table deviates from the corpus mean by
/// `(U x)_b`; over the corpus that deviation has variance `v_b = Σ_j U_bj² λ_j / (N − 1)`
/// (stored components) plus the truncation error `Σ_{j ≥ K} λ_j / ((N − 1) D)` (the mean
/// variance the stored components miss). The prior penalises
/// `k / M · Σ_b (U x)_b² / v_b` over `M` sampled bins that no functional touches — about `k`
/// for a corpus material, like the coefficient prior `xᵀ Λ⁻¹ x` — so that `exp` of the linear
/// model cannot grow freely where nothing is observed.
#[derive(Debug, Clone)]
pub struct TablePrior {
    /// `k × k` precision: `k / M · Σ_b u_b u_bᵀ / v_b`.
    pub precision: DMatrix<f64>,
    /// Number of bins sampled.
    pub bins: usize,
}

impl TablePrior {
    /// The prior for the first `local.k` components over every `step`-th unobserved bin of
    /// each channel.
    pub fn new(model: &reduce::Model, local: &LocalModel, step: usize) -> Result<Self> {
        check_model_grid(model)?;
        let k = local.k;
        let kk = model.components();
        let nb = brdf::BINS;
        let n = model.names.len().max(2) as f64;
        let lam: Vec<f64> = model.pca.eigenvalues[..kk]
            .iter()
            .map(|l| l / (n - 1.0))
            .collect();
        let truncation = model.pca.eigenvalues[kk.min(model.pca.eigenvalues.len())..]
            .iter()
            .sum::<f64>()
            / (n - 1.0)
            / model.pca.dim as f64;
        let step = step.max(1);
        let sampled: Vec<usize> = (0..3 * nb)
            .step_by(step)
            .filter(|d| local.local((d % nb) as u32).is_none())
            .collect();
        let parts: Vec<Vec<f64>> = sampled
            .par_chunks(4096)
            .map(|ds| {
                let mut p = vec![0.0; k * k];
                for &d in ds {
                    let u = &model.pca.basis[d * kk..(d + 1) * kk];
                    let v: f64 = u
                        .iter()
                        .zip(&lam)
                        .map(|(a, l)| (*a as f64) * (*a as f64) * l)
                        .sum::<f64>()
                        + truncation;
                    if v <= 0.0 {
                        continue;
                    }
                    for a in 0..k {
                        let ua = u[a] as f64 / v;
                        let row = &mut p[a * k..(a + 1) * k];
                        for b in a..k {
                            row[b] += ua * u[b] as f64;
                        }
                    }
                }
                p
            })
            .collect();
        let m = sampled.len().max(1) as f64;
        let mut precision = DMatrix::zeros(k, k);
        for p in parts {
            for a in 0..k {
                for b in a..k {
                    precision[(a, b)] += p[a * k + b] * k as f64 / m;
                }
            }
        }
        for a in 0..k {
            for b in 0..a {
                precision[(a, b)] = precision[(b, a)];
            }
        }
        Ok(TablePrior {
            precision,
            bins: sampled.len(),
        })
    }
}

/// 1.4826 × median absolute residual (floored at 10⁻⁶).
pub fn robust_scale(r: &[f64]) -> f64 {
    if r.is_empty() {
        return 1.0;
    }
    let mut a: Vec<f64> = r.iter().map(|v| v.abs()).collect();
    let m = a.len() / 2;
    a.select_nth_unstable_by(m, |x, y| x.total_cmp(y));
    (1.4826 * a[m]).max(1e-6)
}
