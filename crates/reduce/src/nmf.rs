//! Non-negative matrix factorisation with Lee–Seung multiplicative updates for the divergence
//! objective of the seed (eq. 2.38): maximise `Σ y log(UX) − UX`, i.e. minimise the generalised
//! Kullback–Leibler divergence `Σ y log(y / UX) − y + UX`.
//!
//! Data are `n` materials of `dim` non-negative values (linear BRDF values, not logs), stored
//! material-major as in [`crate::corpus::Corpus`]. The factors are a basis `U` (`dim × r`,
//! stored dimension-major) and weights `X` (`r × n`). Each update streams the data in blocks
//! with rayon and never forms `UX`: two passes per iteration (one per factor).

use rand::{Rng, SeedableRng};
use rayon::prelude::*;

use crate::error::{ReduceError, Result};

const BLOCK: usize = 4096;
const TINY: f64 = 1e-30;

/// Parameters of [`nmf`].
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct NmfConfig {
    /// Number of basis vectors `r`.
    pub rank: usize,
    /// Number of multiplicative update iterations.
    pub iterations: usize,
    /// Seed of the random initialisation (ChaCha8).
    pub seed: u64,
    /// Evaluate the divergence at every iteration (costs one logarithm per value and pass);
    /// otherwise only before the first and after the last iteration.
    pub track_divergence: bool,
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
    /// Generalised KL divergence before each iteration (or only the first, see
    /// [`NmfConfig::track_divergence`]) and after the last one.
    pub divergence: Vec<f64>,
    /// `‖Y − UX‖_F / ‖Y‖_F` of the final factors.
    pub relative_error: f64,
}

/// Factorises `n` non-negative rows of length `dim` (row-major `y`).
pub fn nmf(y: &[f32], n: usize, dim: usize, cfg: &NmfConfig) -> Result<Nmf> {
    if y.len() != n * dim {
        return Err(ReduceError::Dimension {
            what: "NMF data length (n × dim)",
            expected: n * dim,
            got: y.len(),
        });
    }
    let r = cfg.rank;
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
    let mean = y.par_iter().map(|&v| v as f64).sum::<f64>() / y.len() as f64;
    if mean.is_nan() || mean <= 0.0 {
        return Err(ReduceError::NotEnoughData("NMF input is all zero".into()));
    }
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(cfg.seed);
    // E[(UX)] = r · E[u] · E[x] = mean with u, x uniform on (0, 1) and (0, 4·mean/r).
    let mut basis: Vec<f32> = (0..dim * r).map(|_| rng.gen_range(0.01f32..1.0)).collect();
    let xs = 4.0 * mean / r as f64;
    let mut weights: Vec<f64> = (0..r * n).map(|_| rng.gen_range(0.01..1.0) * xs).collect();
    let mut divergence = Vec::with_capacity(cfg.iterations + 1);
    for it in 0..cfg.iterations {
        // Pass 1: X update (and divergence of the current factors).
        let with_div = cfg.track_divergence || it == 0;
        let (num, usum, div) = y_over_ux_pass(y, n, dim, r, &basis, &weights, with_div);
        if with_div {
            divergence.push(div);
        }
        for a in 0..r {
            for i in 0..n {
                weights[a * n + i] *= num[a * n + i] / usum[a].max(TINY);
            }
        }
        // Pass 2: U update with the new X.
        let xsum: Vec<f64> = (0..r)
            .map(|a| weights[a * n..(a + 1) * n].iter().sum())
            .collect();
        let w = &weights;
        basis
            .par_chunks_mut(BLOCK * r)
            .enumerate()
            .for_each(|(b, ub)| {
                let d0 = b * BLOCK;
                let len = ub.len() / r;
                let mut num = vec![0.0f64; len * r];
                for i in 0..n {
                    let xi: Vec<f64> = (0..r).map(|a| w[a * n + i]).collect();
                    let row = &y[i * dim + d0..i * dim + d0 + len];
                    for (j, &yv) in row.iter().enumerate() {
                        if yv == 0.0 {
                            continue;
                        }
                        let u = &ub[j * r..(j + 1) * r];
                        let ux: f64 = u.iter().zip(&xi).map(|(&a, b)| a as f64 * b).sum();
                        let ratio = yv as f64 / ux.max(TINY);
                        for (nm, x) in num[j * r..(j + 1) * r].iter_mut().zip(&xi) {
                            *nm += x * ratio;
                        }
                    }
                }
                for (u, nm) in ub
                    .iter_mut()
                    .zip(num.chunks_exact(r).flat_map(|c| c.iter().enumerate()))
                {
                    *u = (*u as f64 * nm.1 / xsum[nm.0].max(TINY)) as f32;
                }
            });
        tracing::debug!(iteration = it, divergence = div, "NMF");
    }
    let (_, _, div) = y_over_ux_pass(y, n, dim, r, &basis, &weights, true);
    divergence.push(div);
    let relative_error = frobenius_error(y, n, dim, r, &basis, &weights);
    Ok(Nmf {
        rank: r,
        basis,
        weights,
        divergence,
        relative_error,
    })
}

/// Returns `(Σ_d U[d][a] Y[i][d] / (UX)[d][i]` as `r × n`, `Σ_d U[d][a]`, divergence`).
fn y_over_ux_pass(
    y: &[f32],
    n: usize,
    dim: usize,
    r: usize,
    basis: &[f32],
    w: &[f64],
    with_div: bool,
) -> (Vec<f64>, Vec<f64>, f64) {
    let zero = || (vec![0.0f64; r * n], vec![0.0f64; r], 0.0f64);
    basis
        .par_chunks(BLOCK * r)
        .enumerate()
        .fold(zero, |(mut num, mut usum, mut div), (b, ub)| {
            let d0 = b * BLOCK;
            let len = ub.len() / r;
            for u in ub.chunks_exact(r) {
                for (s, &v) in usum.iter_mut().zip(u) {
                    *s += v as f64;
                }
            }
            for i in 0..n {
                let xi: Vec<f64> = (0..r).map(|a| w[a * n + i]).collect();
                let mut acc = vec![0.0f64; r];
                let row = &y[i * dim + d0..i * dim + d0 + len];
                for (j, &yv) in row.iter().enumerate() {
                    let u = &ub[j * r..(j + 1) * r];
                    let ux: f64 = u
                        .iter()
                        .zip(&xi)
                        .map(|(&a, b)| a as f64 * b)
                        .sum::<f64>()
                        .max(TINY);
                    let yv = yv as f64;
                    if yv > 0.0 {
                        let ratio = yv / ux;
                        if with_div {
                            div += yv * ratio.ln() - yv + ux;
                        }
                        for (a, &uv) in acc.iter_mut().zip(u) {
                            *a += uv as f64 * ratio;
                        }
                    } else if with_div {
                        div += ux;
                    }
                }
                for a in 0..r {
                    num[a * n + i] += acc[a];
                }
            }
            (num, usum, div)
        })
        .reduce(zero, |(mut a, mut b, c), (x, y, z)| {
            a.iter_mut().zip(&x).for_each(|(p, q)| *p += q);
            b.iter_mut().zip(&y).for_each(|(p, q)| *p += q);
            (a, b, c + z)
        })
}

fn frobenius_error(y: &[f32], n: usize, dim: usize, r: usize, basis: &[f32], w: &[f64]) -> f64 {
    let (e, t) = basis
        .par_chunks(BLOCK * r)
        .enumerate()
        .map(|(b, ub)| {
            let d0 = b * BLOCK;
            let (mut e, mut t) = (0.0f64, 0.0f64);
            for i in 0..n {
                let xi: Vec<f64> = (0..r).map(|a| w[a * n + i]).collect();
                for (j, u) in ub.chunks_exact(r).enumerate() {
                    let ux: f64 = u.iter().zip(&xi).map(|(&a, b)| a as f64 * b).sum();
                    let yv = y[i * dim + d0 + j] as f64;
                    e += (yv - ux) * (yv - ux);
                    t += yv * yv;
                }
            }
            (e, t)
        })
        .reduce(|| (0.0, 0.0), |a, b| (a.0 + b.0, a.1 + b.1));
    (e / t.max(TINY)).sqrt()
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

    #[test]
    fn divergence_never_increases_and_low_rank_data_is_recovered() {
        let (n, dim) = (15, 3000);
        let y = exact_rank(n, dim, 3, 4);
        let f = nmf(
            &y,
            n,
            dim,
            &NmfConfig {
                rank: 3,
                iterations: 300,
                seed: 2,
                track_divergence: true,
            },
        )
        .unwrap();
        // Lee & Seung: the multiplicative updates never increase the divergence.
        for w in f.divergence.windows(2) {
            assert!(w[1] <= w[0] * (1.0 + 1e-9), "{} -> {}", w[0], w[1]);
        }
        assert!(
            f.relative_error < 0.05,
            "relative error {}",
            f.relative_error
        );
        assert!(f.basis.iter().all(|&v| v >= 0.0) && f.weights.iter().all(|&v| v >= 0.0));
        // A factorisation of too low a rank cannot be as good.
        let f1 = nmf(
            &y,
            n,
            dim,
            &NmfConfig {
                rank: 1,
                iterations: 300,
                seed: 2,
                track_divergence: false,
            },
        )
        .unwrap();
        assert!(f1.relative_error > 2.0 * f.relative_error);
    }

    #[test]
    fn rejects_negative_and_non_finite_data() {
        let cfg = NmfConfig {
            rank: 1,
            iterations: 1,
            seed: 0,
            track_divergence: false,
        };
        assert!(nmf(&[1.0, -1.0], 1, 2, &cfg).is_err());
        assert!(nmf(&[1.0, f32::NAN], 1, 2, &cfg).is_err());
        assert!(nmf(&[1.0, 1.0], 1, 3, &cfg).is_err());
    }
}
