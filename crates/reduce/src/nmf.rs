//! Non-negative matrix factorisation `Y ≈ U X` of a corpus (thesis §2.5.1, §4.2.1).

use rand::{Rng, SeedableRng};
use rayon::prelude::*;

use crate::error::{ReduceError, Result};
use crate::ordered::{group_size, reduce_in_order, sum_in_order};

/// Number of dimensions per streamed block (a multiple of the SIMD width).
pub const BLOCK: usize = 1024;
const LANES: usize = 16;
/// Floor of `(UX)` in the divergence updates, as scikit-learn's (`f32` machine epsilon).
const UX_FLOOR: f32 = f32::EPSILON;
const TINY: f64 = 1e-30;

/// The objective and its update rule.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Solver {
    /// Generalised Kullback–Leibler divergence (thesis eq. 2.38), multiplicative updates.
    KullbackLeibler,
    /// `½ ‖Y − UX‖²_F`, multiplicative updates.
    FrobeniusMultiplicative,
    /// `½ ‖Y − UX‖²_F`, hierarchical alternating least squares.
    FrobeniusHals,
}

/// Parameters of [`nmf`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct NmfConfig {
    /// Number of basis vectors `r`.
    pub rank: usize,
    /// Maximum number of iterations.
    pub iterations: usize,
    /// Stopping rule: stop after the first iteration whose relative decrease of the objective,
    /// `(f_prev − f) / f_prev`, is below this value. `0` runs all iterations.
    pub tolerance: f64,
    /// Seed of the random initialisation (ChaCha8).
    pub seed: u64,
    /// Objective and update rule.
    pub solver: Solver,
}

impl NmfConfig {
    /// Kullback–Leibler updates at `rank`, at most 200 iterations, tolerance `1e-4`, seed 0.
    pub fn new(rank: usize) -> NmfConfig {
        NmfConfig {
            rank,
            iterations: 200,
            tolerance: 1e-4,
            seed: 0,
            solver: Solver::KullbackLeibler,
        }
    }
}

/// A non-negative factorisation `Y ≈ U X`.
#[derive(Debug, Clone)]
pub struct Nmf {
    /// Rank `r`.
    pub rank: usize,
    /// Basis `U`, dimension-major: `basis[d * r + a]`.
    pub basis: Vec<f32>,
    /// Weights `X`, `weights[a * n + i]` for material `i`.
    pub weights: Vec<f64>,
    /// Objective of the solver (KL divergence, or `½ ‖Y − UX‖²_F`) of the initial factors and
    /// after each iteration: `iterations + 1` values.
    pub objective: Vec<f64>,
    /// Number of iterations run.
    pub iterations: usize,
    /// Whether the stopping rule ended the run (rather than the iteration limit).
    pub converged: bool,
    /// `‖Y − UX‖_F / ‖Y‖_F` of the final factors.
    pub relative_error: f64,
}

/// Random initial factors for `rank`: basis uniform on `(0.01, 1)`, weights uniform on
/// `(0.01, 1) · 4 m / r` (`m` the mean of the data), so that `E[UX] ≈ m`. Returns
/// `(basis (dim × r, dimension-major), weights (r × n))`.
pub fn random_init(
    y: &[f32],
    n: usize,
    dim: usize,
    rank: usize,
    seed: u64,
) -> Result<(Vec<f32>, Vec<f64>)> {
    check_data(y, n, dim, rank)?;
    let mean = sum_in_order(y, |v| v as f64) / y.len() as f64;
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed);
    let basis: Vec<f32> = (0..dim * rank)
        .map(|_| rng.gen_range(0.01f32..1.0))
        .collect();
    let xs = 4.0 * mean / rank as f64;
    let weights: Vec<f64> = (0..rank * n)
        .map(|_| rng.gen_range(0.01..1.0) * xs)
        .collect();
    Ok((basis, weights))
}

/// Non-negative matrix factorisation `Y ≈ U X` of a corpus (thesis §2.5.1, §4.2.1): factorises
/// `n` non-negative rows of length `dim` (row-major `y`) from [`random_init`].
///
/// Data are `n` materials of `dim` non-negative values (linear BRDF values, not logs), stored
/// material-major as in [`Corpus`](crate::Corpus). The factors are a basis `U` (`dim × r`,
/// stored dimension-major) and weights `X` (`r × n`). Three solvers are available
/// ([`Solver`]):
///
/// * [`Solver::KullbackLeibler`]: Lee–Seung multiplicative updates for the divergence
///   objective of the thesis (eq. 2.38): maximise `Σ y log(UX) − UX`, i.e. minimise the
///   generalised Kullback–Leibler divergence `Σ y log(y / UX) − y + UX`.
/// * [`Solver::FrobeniusMultiplicative`]: Lee–Seung multiplicative updates for
///   `½ ‖Y − UX‖²_F`.
/// * [`Solver::FrobeniusHals`]: hierarchical alternating least squares (exact coordinate
///   minimisation of one basis column or weight row at a time) for `½ ‖Y − UX‖²_F`; it
///   usually reaches a lower objective than the multiplicative updates in the same number of
///   iterations at the same cost per iteration.
///
/// Every iteration updates `X` (with `U` fixed) and then `U` (with the new `X`), in that order.
///
/// # Examples
///
/// ```
/// use reduce::{nmf, NmfConfig, Solver};
/// // Three materials of 2000 values: exactly rank 2, non-negative.
/// let (n, dim) = (3, 2000);
/// let y: Vec<f32> = (0..n * dim)
///     .map(|k| {
///         let (i, d) = (k / dim, k % dim);
///         (1 + i) as f32 * (d % 7) as f32 + (3 - i) as f32 * (d % 5) as f32
///     })
///     .collect();
/// let cfg = NmfConfig { rank: 2, tolerance: 1e-6, iterations: 500, ..NmfConfig::new(2) };
/// let f = nmf(&y, n, dim, &cfg).unwrap();
/// assert!(f.relative_error < 0.05);
/// // The divergence never increases from one iteration to the next.
/// assert!(f.objective.windows(2).all(|w| w[1] <= w[0] * (1.0 + 1e-6)));
/// # let _ = Solver::FrobeniusHals;
/// ```
///
/// # Computation
///
/// `UX` is never stored. The basis is kept in blocks of `BLOCK` (1024) dimensions, component-major
/// inside a block, and each iteration is **one** streamed pass over the data: for one block,
/// rayon tasks update the block of `U` from the current `X` and then, with the block of the
/// data still in cache, accumulate the sums the next `X` update needs and the block's share of
/// the objective. The pass therefore reads the data once per iteration, and the objective of
/// every iteration comes at almost no cost; it drives the stopping rule
/// ([`NmfConfig::tolerance`]). The inner loops run over 16 consecutive dimensions with `f32`
/// lanes and are compiled for AVX-512, AVX2 + FMA and portable SSE; the kernel is selected at
/// run time. Sums over a block are `f32`, sums across blocks and everything of size `r × n`
/// are `f64`.
pub fn nmf(y: &[f32], n: usize, dim: usize, cfg: &NmfConfig) -> Result<Nmf> {
    let (basis, weights) = random_init(y, n, dim, cfg.rank, cfg.seed)?;
    nmf_from(y, n, dim, basis, weights, cfg)
}

/// Factorises `y` from given initial factors (`basis` dimension-major `dim × r`, `weights`
/// `r × n`, both non-negative); [`NmfConfig::seed`] is not used.
pub fn nmf_from(
    y: &[f32],
    n: usize,
    dim: usize,
    basis: Vec<f32>,
    weights: Vec<f64>,
    cfg: &NmfConfig,
) -> Result<Nmf> {
    let r = cfg.rank;
    check_data(y, n, dim, r)?;
    ReduceError::check_size("NMF initial basis (dim × r)", dim * r, basis.len())?;
    ReduceError::check_size("NMF initial weights (r × n)", r * n, weights.len())?;
    if basis.iter().any(|v| !(v.is_finite() && *v >= 0.0))
        || weights.iter().any(|v| !(v.is_finite() && *v >= 0.0))
    {
        return Err(ReduceError::InvalidParameter(
            "NMF initial factors must be finite and non-negative".into(),
        ));
    }
    if cfg.tolerance.is_nan() || cfg.tolerance < 0.0 {
        return Err(ReduceError::InvalidParameter(format!(
            "NMF tolerance {}",
            cfg.tolerance
        )));
    }
    let mut st = State::new(y, n, dim, r, &basis, weights, select_kernel());
    let mut objective = Vec::with_capacity(cfg.iterations + 1);
    let mut converged = false;
    let frob = cfg.solver != Solver::KullbackLeibler;
    // The first pass only accumulates (for the first X update and the initial objective).
    let mut acc = st.sweep(if frob {
        Mode::Frob(None)
    } else {
        Mode::Kl(false)
    });
    objective.push(st.objective(&acc, cfg.solver));
    let mut done = 0;
    while done < cfg.iterations {
        st.update_weights(&acc, cfg.solver);
        let mode = match cfg.solver {
            Solver::KullbackLeibler => Mode::Kl(true),
            Solver::FrobeniusMultiplicative => Mode::Frob(Some(false)),
            Solver::FrobeniusHals => Mode::Frob(Some(true)),
        };
        acc = st.sweep(mode);
        let f = st.objective(&acc, cfg.solver);
        done += 1;
        let prev = *objective.last().unwrap_or(&f);
        objective.push(f);
        tracing::debug!(iteration = done, objective = f, "NMF");
        if cfg.tolerance > 0.0 && (prev - f) < cfg.tolerance * prev.abs().max(TINY) {
            converged = true;
            break;
        }
    }
    let fro = if frob {
        acc
    } else {
        st.sweep(Mode::Frob(None))
    };
    let residual = 2.0 * st.objective(&fro, Solver::FrobeniusHals);
    let relative_error = (residual.max(0.0) / st.ysq.max(TINY)).sqrt();
    Ok(Nmf {
        rank: r,
        basis: st.basis(),
        weights: st.x,
        objective,
        iterations: done,
        converged,
        relative_error,
    })
}

/// Generalised Kullback–Leibler divergence `Σ y ln(y / UX) − y + UX` of given factors,
/// evaluated directly in `f64` (no floor, an independent check of the solver's own figures).
pub fn kl_divergence(y: &[f32], n: usize, dim: usize, basis: &[f32], weights: &[f64]) -> f64 {
    let r = basis.len() / dim.max(1);
    let per_dim = |d: usize| {
        let u = &basis[d * r..(d + 1) * r];
        let mut s = 0.0;
        for i in 0..n {
            let ux: f64 = (0..r).map(|a| u[a] as f64 * weights[a * n + i]).sum();
            let yv = y[i * dim + d] as f64;
            s += if yv > 0.0 {
                yv * (yv / ux).ln() - yv + ux
            } else {
                ux
            };
        }
        s
    };
    let parts = (0..dim).into_par_iter().fold_chunks(
        group_size(dim, 8).max(4096),
        || 0.0,
        |s, d| s + per_dim(d),
    );
    reduce_in_order(parts, || 0.0, |a, b| a + b)
}

fn check_data(y: &[f32], n: usize, dim: usize, r: usize) -> Result<()> {
    ReduceError::check_size("NMF data length (n × dim)", n * dim, y.len())?;
    if r == 0 || n == 0 || dim == 0 {
        return Err(ReduceError::InvalidParameter(format!(
            "NMF rank {r} on {n} × {dim} data"
        )));
    }
    if y.par_iter().any(|v| !v.is_finite()) {
        return Err(ReduceError::NonFinite("NMF input"));
    }
    if y.par_iter().any(|&v| v < 0.0) {
        return Err(ReduceError::InvalidParameter(
            "NMF input has negative values".into(),
        ));
    }
    if !y.par_iter().any(|&v| v > 0.0) {
        return Err(ReduceError::NotEnoughData("NMF input is all zero".into()));
    }
    Ok(())
}

/// What one pass does with each block.
#[derive(Debug, Clone, Copy)]
enum Mode {
    /// Divergence: update the block of `U` first (`true`) or not, then accumulate.
    Kl(bool),
    /// Frobenius: update the block of `U` by HALS (`Some(true)`), by multiplicative updates
    /// (`Some(false)`) or not at all, then accumulate.
    Frob(Option<bool>),
}

/// Sums of one pass. `num[i * r + a]`: divergence `Σ_d U[d][a] y / UX`, Frobenius
/// `Σ_d U[d][a] y`. `ugram`: divergence `Σ_d U[d][a]` (`r` values), Frobenius `UᵀU` (`r × r`).
/// `obj`: divergence of the block sums.
struct Acc {
    num: Vec<f64>,
    ugram: Vec<f64>,
    obj: f64,
}

/// Shared, read-only inputs of one pass.
struct Pass<'a> {
    y: &'a [f32],
    n: usize,
    dim: usize,
    r: usize,
    /// Weights material-major, `xt[i * r + a]`.
    xt: &'a [f32],
    /// Divergence: `1 / Σ_i X[a][i]`; Frobenius: `XXᵀ` (`r × r`).
    xstat: &'a [f32],
    mode: Mode,
}

/// Per-task scratch.
struct Scratch {
    ybuf: Vec<f32>,
    ux: Vec<f32>,
    ratio: Vec<f32>,
    term: Vec<f32>,
    numu: Vec<f32>,
}

type Kernel = fn(&Pass, usize, &mut [f32], &mut Acc, &mut Scratch);

struct State<'a> {
    y: &'a [f32],
    n: usize,
    dim: usize,
    r: usize,
    /// Basis blocks: block `b`, component `a`, offset `j` at `u[(b * r + a) * BLOCK + j]`; zero
    /// beyond `dim`.
    u: Vec<f32>,
    x: Vec<f64>,
    ysq: f64,
    kernel: Kernel,
}

impl<'a> State<'a> {
    fn new(
        y: &'a [f32],
        n: usize,
        dim: usize,
        r: usize,
        basis: &[f32],
        x: Vec<f64>,
        kernel: Kernel,
    ) -> Self {
        let nb = dim.div_ceil(BLOCK);
        let mut u = vec![0.0f32; nb * r * BLOCK];
        u.par_chunks_mut(r * BLOCK).enumerate().for_each(|(b, ub)| {
            let d0 = b * BLOCK;
            for j in 0..BLOCK.min(dim - d0) {
                for a in 0..r {
                    ub[a * BLOCK + j] = basis[(d0 + j) * r + a];
                }
            }
        });
        let ysq = sum_in_order(y, |v| v as f64 * v as f64);
        State {
            y,
            n,
            dim,
            r,
            u,
            x,
            ysq,
            kernel,
        }
    }

    fn basis(&self) -> Vec<f32> {
        let r = self.r;
        let mut out = vec![0.0f32; self.dim * r];
        out.par_chunks_mut(BLOCK * r)
            .enumerate()
            .for_each(|(b, ob)| {
                let ub = &self.u[b * r * BLOCK..(b + 1) * r * BLOCK];
                for (j, o) in ob.chunks_exact_mut(r).enumerate() {
                    for (a, v) in o.iter_mut().enumerate() {
                        *v = ub[a * BLOCK + j];
                    }
                }
            });
        out
    }

    fn xsum(&self) -> Vec<f64> {
        let n = self.n;
        (0..self.r)
            .map(|a| self.x[a * n..(a + 1) * n].iter().sum())
            .collect()
    }

    fn xxt(&self) -> Vec<f64> {
        let (n, r) = (self.n, self.r);
        let mut g = vec![0.0; r * r];
        for a in 0..r {
            for b in 0..r {
                g[a * r + b] = (0..n).map(|i| self.x[a * n + i] * self.x[b * n + i]).sum();
            }
        }
        g
    }

    /// One pass over the data with the current `X`.
    fn sweep(&mut self, mode: Mode) -> Acc {
        let (n, r) = (self.n, self.r);
        let xt: Vec<f32> = (0..n * r)
            .map(|k| self.x[(k % r) * n + k / r] as f32)
            .collect();
        let xstat: Vec<f32> = match mode {
            Mode::Kl(_) => self
                .xsum()
                .iter()
                .map(|&s| if s > TINY { (1.0 / s) as f32 } else { 0.0 })
                .collect(),
            Mode::Frob(_) => self.xxt().iter().map(|&v| v as f32).collect(),
        };
        let pass = Pass {
            y: self.y,
            n,
            dim: self.dim,
            r,
            xt: &xt,
            xstat: &xstat,
            mode,
        };
        let ng = match mode {
            Mode::Kl(_) => r,
            Mode::Frob(_) => r * r,
        };
        let kernel = self.kernel;
        let zero = || Acc {
            num: vec![0.0; n * r],
            ugram: vec![0.0; ng],
            obj: 0.0,
        };
        let scratch = || Scratch {
            ybuf: vec![0.0; BLOCK],
            ux: vec![0.0; BLOCK],
            ratio: vec![0.0; BLOCK],
            term: vec![0.0; BLOCK],
            numu: vec![0.0; r * BLOCK],
        };
        let blocks = self.u.len() / (r * BLOCK).max(1);
        let parts = self
            .u
            .par_chunks_mut(r * BLOCK)
            .enumerate()
            .fold_chunks(
                group_size(blocks, (n * r + ng) * 8),
                || (zero(), scratch()),
                |(mut acc, mut s), (b, ub)| {
                    kernel(&pass, b, ub, &mut acc, &mut s);
                    (acc, s)
                },
            )
            .map(|(acc, _)| acc);
        reduce_in_order(parts, zero, |mut a, b| {
            a.num.iter_mut().zip(&b.num).for_each(|(p, q)| *p += q);
            a.ugram.iter_mut().zip(&b.ugram).for_each(|(p, q)| *p += q);
            a.obj += b.obj;
            a
        })
    }

    /// Objective of the current `U` and `X` from the sums of a pass made with them.
    fn objective(&self, acc: &Acc, solver: Solver) -> f64 {
        let (n, r) = (self.n, self.r);
        match solver {
            // Σ y φ(UX / y) over y > 0 plus Σ UX over y = 0, summed by the kernel.
            Solver::KullbackLeibler => acc.obj,
            Solver::FrobeniusMultiplicative | Solver::FrobeniusHals => {
                let g = self.xxt();
                let mut cross = 0.0;
                for i in 0..n {
                    for a in 0..r {
                        cross += self.x[a * n + i] * acc.num[i * r + a];
                    }
                }
                let quad: f64 = acc.ugram.iter().zip(&g).map(|(p, q)| p * q).sum();
                0.5 * (self.ysq - 2.0 * cross + quad)
            }
        }
    }

    /// `X` update from the sums of a pass made with the current `U` and `X`.
    fn update_weights(&mut self, acc: &Acc, solver: Solver) {
        let (n, r) = (self.n, self.r);
        let x = &mut self.x;
        match solver {
            Solver::KullbackLeibler => {
                for a in 0..r {
                    let us = acc.ugram[a];
                    for i in 0..n {
                        x[a * n + i] *= acc.num[i * r + a] / us.max(TINY);
                    }
                }
            }
            Solver::FrobeniusMultiplicative => {
                let g = &acc.ugram;
                let old = x.clone();
                for a in 0..r {
                    for i in 0..n {
                        let den: f64 = (0..r).map(|b| g[a * r + b] * old[b * n + i]).sum();
                        x[a * n + i] *= acc.num[i * r + a] / den.max(TINY);
                    }
                }
            }
            Solver::FrobeniusHals => {
                let g = &acc.ugram;
                for a in 0..r {
                    let gaa = g[a * r + a];
                    if gaa <= TINY {
                        continue;
                    }
                    for i in 0..n {
                        let gx: f64 = (0..r).map(|b| g[a * r + b] * x[b * n + i]).sum();
                        let v = x[a * n + i] + (acc.num[i * r + a] - gx) / gaa;
                        x[a * n + i] = v.max(0.0);
                    }
                }
            }
        }
    }
}

fn select_kernel() -> Kernel {
    #[cfg(target_arch = "x86_64")]
    {
        if std::arch::is_x86_feature_detected!("avx512f") {
            return block_avx512;
        }
        if std::arch::is_x86_feature_detected!("avx2") && std::arch::is_x86_feature_detected!("fma")
        {
            return block_avx2;
        }
    }
    block_portable
}

/// A kernel compiled for a set of CPU features, entered only where the CPU has them.
macro_rules! simd_kernel {
    ($name:ident, $features:literal) => {
        #[cfg(target_arch = "x86_64")]
        fn $name(p: &Pass, b: usize, ub: &mut [f32], acc: &mut Acc, s: &mut Scratch) {
            #[target_feature(enable = $features)]
            unsafe fn kernel(p: &Pass, b: usize, ub: &mut [f32], acc: &mut Acc, s: &mut Scratch) {
                block::<true>(p, b, ub, acc, s)
            }
            // SAFETY: `select_kernel` picks this kernel only after `is_x86_feature_detected!`
            // confirmed every feature it is compiled for.
            unsafe { kernel(p, b, ub, acc, s) }
        }
    };
}

simd_kernel!(block_avx512, "avx512f,avx2,fma");
simd_kernel!(block_avx2, "avx2,fma");

fn block_portable(p: &Pass, b: usize, ub: &mut [f32], acc: &mut Acc, s: &mut Scratch) {
    block::<false>(p, b, ub, acc, s)
}

use crate::gram::{dot_lanes as dot, fmadd};

/// `ln x` for positive normal `x`, branch-free: `x = 2^e m` with `m ∈ [√½, √2)`, and
/// `ln m = 2 atanh(s)`, `s = (m − 1)/(m + 1)`, `|s| < 0.172`, by its series to `s⁹`
/// (truncation below `4·10⁻¹⁰`).
#[inline(always)]
fn ln_pos<const FMA: bool>(x: f32) -> f32 {
    let bits = x.to_bits();
    // Shift the mantissa range from [1, 2) to [√½, √2) by borrowing from the exponent.
    let t = bits.wrapping_sub(0x3f35_04f3); // bits of √½
    let e = ((t as i32) >> 23) as f32;
    let m = f32::from_bits((t & 0x007f_ffff).wrapping_add(0x3f35_04f3));
    let s = (m - 1.0) / (m + 1.0);
    let s2 = s * s;
    let p = fmadd::<FMA>(
        fmadd::<FMA>(
            fmadd::<FMA>(fmadd::<FMA>(1.0 / 9.0, s2, 1.0 / 7.0), s2, 1.0 / 5.0),
            s2,
            1.0 / 3.0,
        ),
        s2,
        1.0,
    );
    fmadd::<FMA>(e, std::f32::consts::LN_2, 2.0 * s * p)
}

/// The divergence term `y ln(y / u) − y + u` of one value with `y > 0`, `u > 0`, given
/// `ratio = y / u`, without cancellation when `u ≈ y`: with `δ = y − u` and
/// `s = δ / (y + u)`, `ln(y / u) = 2 atanh s`, so the term is
/// `δ s + 2 y s³ (1/3 + s²/5 + s⁴/7 + …)` (used for `|s| < 1/4`, series to `s¹³`);
/// elsewhere `u − y + y ln(ratio)` has no cancellation to fear.
#[inline(always)]
fn kl_term<const FMA: bool>(y: f32, u: f32, ratio: f32) -> f32 {
    let d = y - u;
    let s = d / (y + u);
    let s2 = s * s;
    let series = fmadd::<FMA>(
        fmadd::<FMA>(
            fmadd::<FMA>(
                fmadd::<FMA>(fmadd::<FMA>(1.0 / 13.0, s2, 1.0 / 11.0), s2, 1.0 / 9.0),
                s2,
                1.0 / 7.0,
            ),
            s2,
            1.0 / 5.0,
        ),
        s2,
        1.0 / 3.0,
    );
    let near = fmadd::<FMA>(2.0 * y * s * s2, series, d * s);
    let far = fmadd::<FMA>(y, ln_pos::<FMA>(ratio), -d);
    if s.abs() < 0.25 {
        near
    } else {
        far
    }
}

/// One block of one pass.
#[inline(always)]
fn block<const FMA: bool>(p: &Pass, b: usize, ub: &mut [f32], acc: &mut Acc, s: &mut Scratch) {
    let (n, dim, r) = (p.n, p.dim, p.r);
    let d0 = b * BLOCK;
    let len = BLOCK.min(dim - d0);
    // --- Update of this block of U from the current X.
    let update = match p.mode {
        Mode::Kl(u) => u,
        Mode::Frob(u) => u.is_some(),
    };
    if update {
        let numu = &mut s.numu[..r * BLOCK];
        numu.fill(0.0);
        for i in 0..n {
            let yr = row(&p.y[i * dim + d0..i * dim + d0 + len], &mut s.ybuf);
            let xi = &p.xt[i * r..(i + 1) * r];
            match p.mode {
                Mode::Kl(_) => {
                    ux_block::<FMA>(ub, xi, &mut s.ux);
                    for ((q, &yv), &u) in s.ratio.iter_mut().zip(yr).zip(&s.ux) {
                        *q = yv / u.max(UX_FLOOR);
                    }
                    for (a, &xa) in xi.iter().enumerate() {
                        let na = &mut numu[a * BLOCK..(a + 1) * BLOCK];
                        for (v, &q) in na.iter_mut().zip(&s.ratio) {
                            *v = fmadd::<FMA>(xa, q, *v);
                        }
                    }
                }
                Mode::Frob(_) => {
                    for (a, &xa) in xi.iter().enumerate() {
                        let na = &mut numu[a * BLOCK..(a + 1) * BLOCK];
                        for (v, &yv) in na.iter_mut().zip(yr) {
                            *v = fmadd::<FMA>(xa, yv, *v);
                        }
                    }
                }
            }
        }
        match p.mode {
            Mode::Kl(_) => {
                for a in 0..r {
                    let inv = p.xstat[a];
                    for (u, &v) in ub[a * BLOCK..(a + 1) * BLOCK]
                        .iter_mut()
                        .zip(&numu[a * BLOCK..(a + 1) * BLOCK])
                    {
                        *u *= v * inv;
                    }
                }
            }
            Mode::Frob(Some(false)) => {
                // U[j][a] *= (Y Xᵀ)[j][a] / (U XXᵀ)[j][a], with the old U on the right.
                let g = p.xstat;
                let ux = &mut s.ux;
                for a in 0..r {
                    ux.fill(0.0);
                    for c in 0..r {
                        let gc = g[c * r + a];
                        for (o, &u) in ux.iter_mut().zip(&ub[c * BLOCK..(c + 1) * BLOCK]) {
                            *o = fmadd::<FMA>(gc, u, *o);
                        }
                    }
                    let na = &mut numu[a * BLOCK..(a + 1) * BLOCK];
                    for (v, &d) in na.iter_mut().zip(ux.iter()) {
                        *v /= d.max(f32::MIN_POSITIVE);
                    }
                }
                for (u, v) in ub.iter_mut().zip(numu.iter()) {
                    *u *= v;
                }
            }
            Mode::Frob(_) => {
                // HALS: column a of U minimises the objective with the others fixed.
                let g = p.xstat;
                let ux = &mut s.ux;
                for a in 0..r {
                    let gaa = g[a * r + a];
                    if gaa <= 0.0 {
                        continue;
                    }
                    ux.copy_from_slice(&numu[a * BLOCK..(a + 1) * BLOCK]);
                    for c in 0..r {
                        let gc = -g[c * r + a];
                        if c == a {
                            continue;
                        }
                        for (o, &u) in ux.iter_mut().zip(&ub[c * BLOCK..(c + 1) * BLOCK]) {
                            *o = fmadd::<FMA>(gc, u, *o);
                        }
                    }
                    let inv = 1.0 / gaa;
                    for (u, &v) in ub[a * BLOCK..(a + 1) * BLOCK].iter_mut().zip(ux.iter()) {
                        *u = (v * inv).max(0.0);
                    }
                }
                // Dimensions beyond `dim` stay zero (their data are zero).
                for a in 0..r {
                    ub[a * BLOCK + len..(a + 1) * BLOCK].fill(0.0);
                }
            }
        }
    }
    // --- Sums for the next X update and the objective, with this block of U.
    match p.mode {
        Mode::Kl(_) => {
            for a in 0..r {
                acc.ugram[a] += ub[a * BLOCK..(a + 1) * BLOCK]
                    .iter()
                    .map(|&v| v as f64)
                    .sum::<f64>();
            }
        }
        Mode::Frob(_) => {
            for a in 0..r {
                for c in a..r {
                    let v = dot::<FMA>(
                        &ub[a * BLOCK..(a + 1) * BLOCK],
                        &ub[c * BLOCK..(c + 1) * BLOCK],
                    ) as f64;
                    acc.ugram[a * r + c] += v;
                    if c != a {
                        acc.ugram[c * r + a] += v;
                    }
                }
            }
        }
    }
    for i in 0..n {
        let yr = row(&p.y[i * dim + d0..i * dim + d0 + len], &mut s.ybuf);
        let xi = &p.xt[i * r..(i + 1) * r];
        match p.mode {
            Mode::Kl(_) => {
                ux_block::<FMA>(ub, xi, &mut s.ux);
                for (((q, t), &yv), &ux) in
                    s.ratio.iter_mut().zip(s.term.iter_mut()).zip(yr).zip(&s.ux)
                {
                    let u = ux.max(UX_FLOOR);
                    let ratio = yv / u;
                    *q = ratio;
                    // The divergence term for y > 0, UX for y = 0.
                    let kl = kl_term::<FMA>(yv, u, ratio.max(f32::MIN_POSITIVE));
                    *t = if yv > 0.0 { kl } else { ux };
                }
                for a in 0..r {
                    let d = dot::<FMA>(&ub[a * BLOCK..(a + 1) * BLOCK], &s.ratio);
                    acc.num[i * r + a] += d as f64;
                }
                acc.obj += lane_sum(&s.term);
            }
            Mode::Frob(_) => {
                for a in 0..r {
                    let d = dot::<FMA>(&ub[a * BLOCK..(a + 1) * BLOCK], yr);
                    acc.num[i * r + a] += d as f64;
                }
            }
        }
    }
}

/// `ux[j] = Σ_a xi[a] ub[a][j]` over one block.
#[inline(always)]
fn ux_block<const FMA: bool>(ub: &[f32], xi: &[f32], ux: &mut [f32]) {
    for (c, out) in ux.chunks_exact_mut(LANES).enumerate() {
        let mut acc = [0.0f32; LANES];
        for (a, &xa) in xi.iter().enumerate() {
            let ua = &ub[a * BLOCK + c * LANES..a * BLOCK + (c + 1) * LANES];
            for l in 0..LANES {
                acc[l] = fmadd::<FMA>(xa, ua[l], acc[l]);
            }
        }
        out.copy_from_slice(&acc);
    }
}

/// Sum of a block's values: `f32` lanes, then `f64`.
#[inline(always)]
fn lane_sum(v: &[f32]) -> f64 {
    let mut acc = [0.0f32; LANES];
    for c in v.chunks_exact(LANES) {
        for l in 0..LANES {
            acc[l] += c[l];
        }
    }
    acc.iter().map(|&x| x as f64).sum()
}

/// A row segment of [`BLOCK`] values: the data themselves, or a zero-padded copy of a
/// shorter last segment.
#[inline(always)]
fn row<'b>(src: &'b [f32], ybuf: &'b mut [f32]) -> &'b [f32] {
    if src.len() == BLOCK {
        src
    } else {
        ybuf[..src.len()].copy_from_slice(src);
        ybuf[src.len()..].fill(0.0);
        ybuf
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn exact_rank(n: usize, dim: usize, r: usize, seed: u64) -> Vec<f32> {
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed);
        let u: Vec<f64> = (0..dim * r)
            .map(|_| rng.gen_range(0.0..1.0f64).powi(3))
            .collect();
        let x: Vec<f64> = (0..r * n).map(|_| rng.gen_range(0.0..2.0)).collect();
        let mut y = vec![0.0f32; n * dim];
        for i in 0..n {
            for d in 0..dim {
                y[i * dim + d] = (0..r).map(|a| u[d * r + a] * x[a * n + i]).sum::<f64>() as f32;
            }
        }
        y
    }

    /// Non-negative data of higher rank than the factorisation, with exact zeros.
    fn noisy(n: usize, dim: usize, seed: u64) -> Vec<f32> {
        let mut y = exact_rank(n, dim, 4, seed);
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed + 100);
        for v in y.iter_mut() {
            let z: f32 = rng.gen_range(0.0..1.0);
            *v = if z < 0.1 {
                0.0
            } else {
                *v * rng.gen_range(0.5..1.5f32)
            };
        }
        y
    }

    fn cfg(rank: usize, iterations: usize, solver: Solver) -> NmfConfig {
        NmfConfig {
            rank,
            iterations,
            tolerance: 0.0,
            seed: 2,
            solver,
        }
    }

    /// Textbook dense implementation in `f64` (whole `UX` formed at every update), same order
    /// of updates (X, then U), same floor.
    #[allow(clippy::too_many_arguments)]
    fn reference(
        y: &[f32],
        n: usize,
        dim: usize,
        mut u: Vec<f64>,
        mut x: Vec<f64>,
        r: usize,
        iterations: usize,
        solver: Solver,
    ) -> (Vec<f64>, Vec<f64>) {
        let yv = |i: usize, d: usize| y[i * dim + d] as f64;
        let ux = |u: &[f64], x: &[f64]| -> Vec<f64> {
            let mut m = vec![0.0; dim * n];
            for d in 0..dim {
                for i in 0..n {
                    m[d * n + i] = (0..r).map(|a| u[d * r + a] * x[a * n + i]).sum();
                }
            }
            m
        };
        let floor = UX_FLOOR as f64;
        // One term of a multiplicative update's numerator and denominator: the other factor's
        // entry `w`, the datum `y` and the model's value `m` there.
        let term = |w: f64, y: f64, m: f64| match solver {
            Solver::KullbackLeibler => (w * y / m.max(floor), w),
            _ => (w * y, w * m),
        };
        // The update factor: summed numerators over summed denominators of the terms.
        let ratio = |terms: &mut dyn Iterator<Item = (f64, f64, f64)>| {
            let (num, den) = terms.fold((0.0, 0.0), |(num, den), (w, y, m)| {
                let (p, q) = term(w, y, m);
                (num + p, den + q)
            });
            num / den
        };
        for _ in 0..iterations {
            let m = ux(&u, &x);
            let mut nx = x.clone();
            for a in 0..r {
                for i in 0..n {
                    let mut terms = (0..dim).map(|d| (u[d * r + a], yv(i, d), m[d * n + i]));
                    nx[a * n + i] = x[a * n + i] * ratio(&mut terms);
                }
            }
            x = nx;
            let m = ux(&u, &x);
            let mut nu = u.clone();
            for d in 0..dim {
                for a in 0..r {
                    let mut terms = (0..n).map(|i| (x[a * n + i], yv(i, d), m[d * n + i]));
                    nu[d * r + a] = u[d * r + a] * ratio(&mut terms);
                }
            }
            u = nu;
        }
        (u, x)
    }

    #[test]
    fn divergence_never_increases_and_low_rank_data_is_recovered() {
        let (n, dim) = (15, 3000);
        let y = exact_rank(n, dim, 3, 4);
        let f = nmf(&y, n, dim, &cfg(3, 300, Solver::KullbackLeibler)).unwrap();
        assert_eq!(f.objective.len(), 301);
        // Lee & Seung: the multiplicative updates never increase the divergence.
        for w in f.objective.windows(2) {
            assert!(w[1] <= w[0] * (1.0 + 1e-9), "{} -> {}", w[0], w[1]);
        }
        assert!(
            f.relative_error < 0.05,
            "relative error {}",
            f.relative_error
        );
        assert!(f.basis.iter().all(|&v| v >= 0.0) && f.weights.iter().all(|&v| v >= 0.0));
        // A factorisation of too low a rank cannot be as good.
        let f1 = nmf(&y, n, dim, &cfg(1, 300, Solver::KullbackLeibler)).unwrap();
        assert!(f1.relative_error > 2.0 * f.relative_error);
    }

    #[test]
    fn objective_never_increases_per_iteration_for_every_solver() {
        // Several blocks, the last one partial; exact zeros in the data.
        let (n, dim) = (12, 2 * BLOCK + 333);
        let y = noisy(n, dim, 5);
        for solver in [
            Solver::KullbackLeibler,
            Solver::FrobeniusMultiplicative,
            Solver::FrobeniusHals,
        ] {
            let f = nmf(&y, n, dim, &cfg(3, 60, solver)).unwrap();
            assert_eq!(f.iterations, 60);
            for (k, w) in f.objective.windows(2).enumerate() {
                assert!(
                    w[1] <= w[0] * (1.0 + 1e-6),
                    "{solver:?} iteration {k}: {} -> {}",
                    w[0],
                    w[1]
                );
            }
            assert!(f.objective[60] < 0.5 * f.objective[0], "{solver:?}");
        }
    }

    #[test]
    fn reported_divergence_matches_a_direct_f64_evaluation() {
        let (n, dim) = (10, BLOCK + 77);
        let y = noisy(n, dim, 6);
        let (u0, x0) = random_init(&y, n, dim, 4, 3).unwrap();
        let start = kl_divergence(&y, n, dim, &u0, &x0);
        let f = nmf_from(&y, n, dim, u0, x0, &cfg(4, 25, Solver::KullbackLeibler)).unwrap();
        let end = kl_divergence(&y, n, dim, &f.basis, &f.weights);
        assert!((f.objective[0] / start - 1.0).abs() < 1e-4, "{start}");
        assert!((f.objective[25] / end - 1.0).abs() < 1e-4, "{end}");
    }

    #[test]
    fn blocked_parallel_updates_agree_with_a_dense_reference() {
        let (n, dim) = (9, BLOCK + 200);
        let y = noisy(n, dim, 7);
        let r = 3;
        let (u0, x0) = random_init(&y, n, dim, r, 9).unwrap();
        for solver in [Solver::KullbackLeibler, Solver::FrobeniusMultiplicative] {
            let f = nmf_from(&y, n, dim, u0.clone(), x0.clone(), &cfg(r, 10, solver)).unwrap();
            let u0d: Vec<f64> = u0.iter().map(|&v| v as f64).collect();
            let (u, x) = reference(&y, n, dim, u0d, x0.clone(), r, 10, solver);
            let rel = |a: &[f64], b: &[f64]| {
                let num: f64 = a.iter().zip(b).map(|(p, q)| (p - q) * (p - q)).sum();
                let den: f64 = b.iter().map(|q| q * q).sum();
                (num / den).sqrt()
            };
            let fu: Vec<f64> = f.basis.iter().map(|&v| v as f64).collect();
            assert!(rel(&fu, &u) < 1e-4, "{solver:?} basis {}", rel(&fu, &u));
            assert!(
                rel(&f.weights, &x) < 1e-4,
                "{solver:?} weights {}",
                rel(&f.weights, &x)
            );
        }
    }

    #[test]
    fn hals_reaches_a_lower_frobenius_objective_than_multiplicative_updates() {
        let (n, dim) = (16, 1500);
        let y = noisy(n, dim, 8);
        let mu = nmf(&y, n, dim, &cfg(4, 30, Solver::FrobeniusMultiplicative)).unwrap();
        let hals = nmf(&y, n, dim, &cfg(4, 30, Solver::FrobeniusHals)).unwrap();
        assert_eq!(mu.objective[0], hals.objective[0]);
        assert!(
            hals.objective[30] < 0.9 * mu.objective[30],
            "HALS {} vs MU {}",
            hals.objective[30],
            mu.objective[30]
        );
        assert!(hals.relative_error < mu.relative_error);
    }

    #[test]
    fn stopping_rule_ends_the_run_once_progress_is_small() {
        let (n, dim) = (10, 800);
        let y = exact_rank(n, dim, 2, 11);
        let mut c = cfg(2, 2000, Solver::KullbackLeibler);
        c.tolerance = 1e-3;
        let f = nmf(&y, n, dim, &c).unwrap();
        assert!(f.converged && f.iterations < 2000);
        let k = f.iterations;
        let last = (f.objective[k - 1] - f.objective[k]) / f.objective[k - 1];
        assert!(last < 1e-3);
        for k in 1..f.iterations {
            let step = (f.objective[k - 1] - f.objective[k]) / f.objective[k - 1];
            assert!(step >= 1e-3, "should have stopped at iteration {k}");
        }
    }

    #[test]
    fn divergence_term_is_accurate_near_and_far_from_a_perfect_fit() {
        for &y in &[1e-6f32, 0.3, 7.0, 4e4] {
            for k in -400..=400 {
                let q = (k as f64 / 100.0).exp(); // u / y from e^-4 to e^4
                let u = (y as f64 * q) as f32;
                let (yd, ud) = (y as f64, u as f64);
                let exact = yd * (yd / ud).ln() - yd + ud;
                let got = kl_term::<false>(y, u, y / u) as f64;
                assert!(
                    (got - exact).abs() <= 1e-5 * exact + 1e-7 * yd,
                    "y {y} u {u}: {got} vs {exact}"
                );
            }
        }
    }

    #[test]
    fn ln_approximation_is_accurate() {
        for k in 0..2000 {
            let x = 10f64.powf(-30.0 + 60.0 * k as f64 / 2000.0) as f32;
            let e = (ln_pos::<false>(x) as f64 - (x as f64).ln()).abs();
            assert!(e < 2e-6 * (x as f64).ln().abs().max(1.0), "x = {x}");
        }
    }

    #[test]
    fn rejects_negative_and_non_finite_data() {
        let c = cfg(1, 1, Solver::KullbackLeibler);
        assert!(nmf(&[1.0, -1.0], 1, 2, &c).is_err());
        assert!(nmf(&[1.0, f32::NAN], 1, 2, &c).is_err());
        assert!(nmf(&[1.0, 1.0], 1, 3, &c).is_err());
        assert!(nmf(&[0.0, 0.0], 1, 2, &c).is_err());
    }
}
