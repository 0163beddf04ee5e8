//! Principal component analysis through the `N × N` Gram matrix (thesis §2.5.1, §4.1).

use nalgebra::{DMatrix, SymmetricEigen};
use rayon::prelude::*;

use crate::error::{ReduceError, Result};
use crate::gram::{column_means, gram_matrix, BLOCK};
use crate::ordered::{add_into, group_size, reduce_in_order};

/// Eigenvalues below this fraction of the largest are treated as zero (rank deficiency: the
/// centred corpus has rank at most `N − 1`).
pub const RELATIVE_EIGEN_TOLERANCE: f64 = 1e-6;

/// A fitted PCA model: principal component analysis through the `N × N` Gram matrix (thesis
/// §2.5.1, eqs. 2.23–2.31; §4.1, eqs. 4.1–4.3).
///
/// With `Y` the mean-centred `D × N` data matrix, `B = YᵀY = V Λ Vᵀ` (4.1), the principal
/// components are `U = Y V Λ^{-1/2}` (4.2) and the coordinates of the corpus `X = Λ^{1/2} Vᵀ`
/// (4.3). Only the `N × N` matrix is ever decomposed; `U` is formed in one streamed pass.
///
/// # Examples
///
/// ```
/// use reduce::Pca;
///
/// // three vectors of 4 values that differ along one direction only
/// let data = [1.0f32, 2.0, 3.0, 4.0, 2.0, 3.0, 4.0, 5.0, 3.0, 4.0, 5.0, 6.0];
/// let pca = Pca::fit(&data, 3, 4, 2).unwrap();
/// assert_eq!(pca.components, 1); // rank 1 once centred
/// // the third vector comes back from its one coordinate
/// let x = pca.project(&data[8..], 1).unwrap();
/// let back = pca.reconstruct(&x).unwrap();
/// assert!(back.iter().zip(&data[8..]).all(|(a, b)| (a - b).abs() < 1e-5));
/// ```
#[derive(Debug, Clone, PartialEq)]
pub struct Pca {
    /// Length of one data vector (`D`).
    pub dim: usize,
    /// Mean vector (length `D`).
    pub mean: Vec<f32>,
    /// All `N` eigenvalues of the centred Gram matrix, decreasing, negatives clamped to 0.
    /// `eigenvalues[k]` is the squared norm of the corpus along component `k` (eq. 2.30).
    pub eigenvalues: Vec<f64>,
    /// Number of stored components `K`.
    pub components: usize,
    /// Orthonormal basis `U`, stored dimension-major: `basis[d * K + k] = u_k[d]`.
    pub basis: Vec<f32>,
    /// Coordinates of the corpus, `N × K` (row `i` = material `i`, eq. 4.3 transposed).
    pub coords: DMatrix<f64>,
}

impl Pca {
    /// Fits PCA to `n` row-major vectors of length `dim`, keeping at most `k` components
    /// (fewer when the centred data has lower rank).
    pub fn fit(data: &[f32], n: usize, dim: usize, k: usize) -> Result<Pca> {
        if n < 2 {
            return Err(ReduceError::NotEnoughData(format!(
                "PCA needs at least 2 vectors, got {n}"
            )));
        }
        if k == 0 {
            return Err(ReduceError::InvalidParameter(
                "number of components must be positive".into(),
            ));
        }
        let mean = column_means(data, n, dim)?;
        if mean.iter().any(|v| !v.is_finite()) {
            return Err(ReduceError::NonFinite("PCA input"));
        }
        let b = gram_matrix(data, n, dim, Some(&mean))?;
        let (mut eigenvalues, v) = sorted_symmetric_eigen(b);
        for l in eigenvalues.iter_mut() {
            *l = l.max(0.0);
        }
        let lmax = eigenvalues[0];
        if lmax.is_nan() || lmax <= 0.0 {
            return Err(ReduceError::NotEnoughData(
                "all vectors are identical".into(),
            ));
        }
        let rank = eigenvalues
            .iter()
            .filter(|&&l| l > RELATIVE_EIGEN_TOLERANCE * lmax)
            .count();
        let kk = k.min(rank);
        // Coefficients c[i][k] = V[i][k] / sqrt(λ_k), so that u_k = Σ_i c[i][k] (y_i − m).
        let coef: Vec<f32> = (0..n)
            .flat_map(|i| (0..kk).map(move |c| (i, c)))
            .map(|(i, c)| (v[(i, c)] / eigenvalues[c].sqrt()) as f32)
            .collect();
        let mut basis = vec![0.0f32; dim * kk];
        basis
            .par_chunks_mut(BLOCK * kk)
            .enumerate()
            .for_each(|(b, out)| {
                let d0 = b * BLOCK;
                let len = out.len() / kk;
                let mut centred = vec![0.0f32; len];
                for i in 0..n {
                    let row = &data[i * dim + d0..i * dim + d0 + len];
                    for ((c, y), m) in centred.iter_mut().zip(row).zip(&mean[d0..d0 + len]) {
                        *c = y - m;
                    }
                    let ci = &coef[i * kk..(i + 1) * kk];
                    for (o, yc) in out.chunks_exact_mut(kk).zip(&centred) {
                        for (u, c) in o.iter_mut().zip(ci) {
                            *u += c * yc;
                        }
                    }
                }
            });
        tracing::debug!(n, dim, components = kk, "PCA fitted");
        Ok(Pca::assemble(
            dim,
            mean,
            eigenvalues,
            kk,
            basis,
            n,
            |i, c| v[(i, c)],
        ))
    }

    /// A model from the eigen-decomposition of the centred Gram matrix: the corpus
    /// coordinates are `v(i, c) · √λ_c` for the `n × kk` eigenvector entries `v`.
    pub(crate) fn assemble(
        dim: usize,
        mean: Vec<f32>,
        eigenvalues: Vec<f64>,
        kk: usize,
        basis: Vec<f32>,
        n: usize,
        v: impl Fn(usize, usize) -> f64,
    ) -> Pca {
        let coords = DMatrix::from_fn(n, kk, |i, c| v(i, c) * eigenvalues[c].sqrt());
        Pca {
            dim,
            mean,
            eigenvalues,
            components: kk,
            basis,
            coords,
        }
    }

    /// Coordinates of a vector `y` (length `D`) on the first `k` components: `x = U_kᵀ (y − m)`.
    pub fn project(&self, y: &[f32], k: usize) -> Result<Vec<f64>> {
        self.check(y, k)?;
        let kk = self.components;
        let blocks = self.mean.len().div_ceil(BLOCK);
        let parts = self.basis.par_chunks(BLOCK * kk).enumerate().fold_chunks(
            group_size(blocks, k * 8),
            || vec![0.0f64; k],
            |mut acc, (b, chunk)| {
                let d0 = b * BLOCK;
                for (j, u) in chunk.chunks_exact(kk).enumerate() {
                    let yc = (y[d0 + j] - self.mean[d0 + j]) as f64;
                    for (a, uk) in acc.iter_mut().zip(&u[..k]) {
                        *a += *uk as f64 * yc;
                    }
                }
                acc
            },
        );
        Ok(reduce_in_order(parts, || vec![0.0f64; k], add_into))
    }

    /// Coordinates on the first `k` components that best explain `y` where `known[d]` holds
    /// (least squares over the known entries only, with a ridge `ridge · Σ_k x_k² / λ_k`
    /// towards the corpus mean that keeps the fit stable when few entries are known):
    /// `x = argmin Σ_known (m_d + Σ_k x_k u_k[d] − y_d)² + ridge Σ_k x_k² / (λ_k / N)`.
    /// With every entry known and `ridge = 0` this is [`Pca::project`].
    pub fn project_masked(
        &self,
        y: &[f32],
        known: &[bool],
        k: usize,
        ridge: f64,
    ) -> Result<Vec<f64>> {
        Ok(self.project_masked_posterior(y, known, k, ridge)?.0)
    }

    /// [`Pca::project_masked`] and the matrix of its normal equations,
    /// `H = Σ_known u[d] u[d]ᵀ + ridge · diag(N / λ_k)` (`k × k`). Read as a Bayesian fit, with
    /// entries known up to independent errors of variance σ² and the prior `x_k ~ N(0, λ_k / N)`,
    /// `ridge = σ²` makes `x` the posterior mean and `σ² H⁻¹` its covariance.
    pub fn project_masked_posterior(
        &self,
        y: &[f32],
        known: &[bool],
        k: usize,
        ridge: f64,
    ) -> Result<(Vec<f64>, DMatrix<f64>)> {
        self.check(y, k)?;
        ReduceError::check_size("mask length", self.dim, known.len())?;
        if !(ridge.is_finite() && ridge >= 0.0) {
            return Err(ReduceError::InvalidParameter(format!(
                "ridge {ridge} must be finite and non-negative"
            )));
        }
        let kk = self.components;
        let zero = || (DMatrix::<f64>::zeros(k, k), vec![0.0f64; k], 0usize);
        let blocks = self.mean.len().div_ceil(BLOCK);
        let parts = self.basis.par_chunks(BLOCK * kk).enumerate().fold_chunks(
            group_size(blocks, (k * k + k) * 8),
            zero,
            |(mut ata, mut atb, mut count), (b, chunk)| {
                let d0 = b * BLOCK;
                for (j, u) in chunk.chunks_exact(kk).enumerate() {
                    let d = d0 + j;
                    if !known[d] {
                        continue;
                    }
                    count += 1;
                    let r = (y[d] - self.mean[d]) as f64;
                    for a in 0..k {
                        let ua = u[a] as f64;
                        atb[a] += ua * r;
                        for c in a..k {
                            ata[(a, c)] += ua * u[c] as f64;
                        }
                    }
                }
                (ata, atb, count)
            },
        );
        let (mut ata, atb, count) = reduce_in_order(parts, zero, |(a1, b1, c1), (a2, b2, c2)| {
            (a1 + a2, add_into(b1, b2), c1 + c2)
        });
        if count == 0 {
            return Err(ReduceError::InvalidParameter(
                "no known entry to fit the coordinates to".into(),
            ));
        }
        let n = self.coords.nrows().max(1) as f64;
        for a in 0..k {
            for c in 0..a {
                ata[(a, c)] = ata[(c, a)];
            }
            let var = (self.eigenvalues.get(a).copied().unwrap_or(0.0) / n).max(1e-12);
            ata[(a, a)] += ridge / var;
        }
        let rhs = nalgebra::DVector::from_vec(atb);
        let x = ata
            .clone()
            .cholesky()
            .map(|c| c.solve(&rhs))
            .or_else(|| ata.clone().lu().solve(&rhs))
            .ok_or_else(|| {
                ReduceError::InvalidParameter(
                    "the known entries do not determine the coordinates (add a ridge)".into(),
                )
            })?;
        Ok((x.iter().copied().collect(), ata))
    }

    /// The vector `m + Σ_k x_k u_k` for coordinates `x` (its length selects how many components
    /// are used; at most `K`).
    pub fn reconstruct(&self, x: &[f64]) -> Result<Vec<f32>> {
        if x.len() > self.components {
            return Err(ReduceError::Dimension {
                what: "number of coordinates (at most K)",
                expected: self.components,
                got: x.len(),
            });
        }
        if x.iter().any(|v| !v.is_finite()) {
            return Err(ReduceError::NonFinite("PCA coordinates"));
        }
        let kk = self.components;
        let xf: Vec<f32> = x.iter().map(|&v| v as f32).collect();
        let mut out = self.mean.clone();
        out.par_chunks_mut(BLOCK).enumerate().for_each(|(b, o)| {
            let d0 = b * BLOCK;
            for (j, v) in o.iter_mut().enumerate() {
                let u = &self.basis[(d0 + j) * kk..(d0 + j) * kk + xf.len()];
                *v += dot_lanes(u, &xf);
            }
        });
        Ok(out)
    }

    /// Squared distances `‖y − (m + U_k U_kᵀ (y − m))‖²` for each `k` in `ks` (each ≤ K), computed
    /// directly in one pass (no reliance on exact orthonormality), and `‖y − m‖²` as the last entry.
    pub fn residuals(&self, y: &[f32], ks: &[usize]) -> Result<Vec<f64>> {
        let kmax = ks.iter().copied().max().unwrap_or(0);
        self.check(y, kmax)?;
        let x = self.project(y, kmax)?;
        let xf: Vec<f32> = x.iter().map(|&v| v as f32).collect();
        let kk = self.components;
        let nk = ks.len();
        let blocks = self.mean.len().div_ceil(BLOCK);
        let parts = self.basis.par_chunks(BLOCK * kk).enumerate().fold_chunks(
            group_size(blocks, (nk + 1) * 8),
            || vec![0.0f64; nk + 1],
            |mut acc, (b, chunk)| {
                let d0 = b * BLOCK;
                let mut partial = vec![0.0f32; kmax + 1];
                for (j, u) in chunk.chunks_exact(kk).enumerate() {
                    let yc = y[d0 + j] - self.mean[d0 + j];
                    // partial[c] = Σ_{k<c} x_k u_k[d]
                    let mut s = 0.0f32;
                    partial[0] = 0.0;
                    for c in 0..kmax {
                        s += u[c] * xf[c];
                        partial[c + 1] = s;
                    }
                    for (a, &k) in acc.iter_mut().zip(ks) {
                        let r = (yc - partial[k]) as f64;
                        *a += r * r;
                    }
                    acc[nk] += (yc as f64) * (yc as f64);
                }
                acc
            },
        );
        Ok(reduce_in_order(parts, || vec![0.0f64; nk + 1], add_into))
    }

    fn check(&self, y: &[f32], k: usize) -> Result<()> {
        ReduceError::check_size("vector length", self.dim, y.len())?;
        if k > self.components {
            return Err(ReduceError::Dimension {
                what: "number of components (at most K)",
                expected: self.components,
                got: k,
            });
        }
        if y.iter().any(|v| !v.is_finite()) {
            return Err(ReduceError::NonFinite("vector to project"));
        }
        Ok(())
    }
}

/// Relative residual of the corpus when keeping `k` components, for `k = 0..=N`:
/// `sqrt(Σ_{j≥k} λ_j / Σ_j λ_j)` (eq. 2.22, as a fraction of the total centred norm).
pub fn residual_curve(eigenvalues: &[f64]) -> Vec<f64> {
    let total: f64 = eigenvalues.iter().sum();
    let mut out = Vec::with_capacity(eigenvalues.len() + 1);
    let mut tail = total;
    out.push(1.0);
    for l in eigenvalues {
        tail -= l;
        out.push((tail.max(0.0) / total).sqrt());
    }
    out
}

/// Eigen-decomposition of a symmetric matrix with eigenvalues sorted decreasingly (negative
/// ones from round-off clamped to zero) and eigenvectors as the matching columns.
pub fn sorted_symmetric_eigen(m: DMatrix<f64>) -> (Vec<f64>, DMatrix<f64>) {
    let n = m.nrows();
    let eig = SymmetricEigen::new(m);
    let mut order: Vec<usize> = (0..n).collect();
    order.sort_by(|&a, &b| eig.eigenvalues[b].total_cmp(&eig.eigenvalues[a]));
    let vals: Vec<f64> = order.iter().map(|&i| eig.eigenvalues[i]).collect();
    let vecs = DMatrix::from_fn(n, n, |r, c| eig.eigenvectors[(r, order[c])]);
    (vals, vecs)
}

/// Like [`sorted_symmetric_eigen`] but increasing order (used for bottom eigenvectors).
pub fn ascending_symmetric_eigen(m: DMatrix<f64>) -> (Vec<f64>, DMatrix<f64>) {
    let (mut vals, vecs) = sorted_symmetric_eigen(m);
    let n = vals.len();
    vals.reverse();
    let vecs = DMatrix::from_fn(n, n, |r, c| vecs[(r, n - 1 - c)]);
    (vals, vecs)
}

/// `Σ a_k b_k` in eight independent lanes (so the compiler can vectorise it and the sums do
/// not wait on each other), then the lanes and the remainder added.
#[inline]
fn dot_lanes(a: &[f32], b: &[f32]) -> f32 {
    const LANES: usize = 8;
    let mut acc = [0.0f32; LANES];
    let (ca, cb) = (a.chunks_exact(LANES), b.chunks_exact(LANES));
    let (ra, rb) = (ca.remainder(), cb.remainder());
    for (x, y) in ca.zip(cb) {
        for l in 0..LANES {
            acc[l] += x[l] * y[l];
        }
    }
    let mut s: f32 = acc.iter().sum();
    for (x, y) in ra.iter().zip(rb) {
        s += x * y;
    }
    s
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_lane_dot_product_is_the_dot_product_at_every_length() {
        for n in 0..40 {
            let a: Vec<f32> = (0..n).map(|i| (i as f32 * 0.37).sin()).collect();
            let b: Vec<f32> = (0..n).map(|i| (i as f32 * 0.91).cos() - 0.2).collect();
            let exact: f64 = a.iter().zip(&b).map(|(x, y)| *x as f64 * *y as f64).sum();
            assert!((dot_lanes(&a, &b) as f64 - exact).abs() < 1e-5, "n = {n}");
        }
    }
    use rand::{Rng, SeedableRng};

    /// Rank-3 data plus tiny noise in 2000 dimensions.
    fn low_rank(n: usize, dim: usize, seed: u64) -> Vec<f32> {
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed);
        let comps: Vec<Vec<f32>> = (0..3)
            .map(|_| (0..dim).map(|_| rng.gen_range(-1.0..1.0)).collect())
            .collect();
        let offset: Vec<f32> = (0..dim).map(|_| rng.gen_range(-2.0..2.0)).collect();
        let mut data = vec![0.0f32; n * dim];
        for i in 0..n {
            let w: Vec<f32> = (0..3)
                .map(|c| rng.gen_range(-1.0..1.0) * (3 - c) as f32)
                .collect();
            for d in 0..dim {
                data[i * dim + d] = offset[d] + (0..3).map(|c| w[c] * comps[c][d]).sum::<f32>();
            }
        }
        data
    }

    #[test]
    fn basis_is_orthonormal_and_coords_match_projection() {
        let (n, dim) = (12, 2000);
        let data = low_rank(n, dim, 1);
        let pca = Pca::fit(&data, n, dim, 10).unwrap();
        assert_eq!(pca.components, 3, "rank-3 data must give 3 components");
        let k = pca.components;
        for a in 0..k {
            for b in 0..k {
                let dot: f64 = (0..dim)
                    .map(|d| pca.basis[d * k + a] as f64 * pca.basis[d * k + b] as f64)
                    .sum();
                let want = if a == b { 1.0 } else { 0.0 };
                assert!((dot - want).abs() < 1e-4, "u{a}·u{b} = {dot}");
            }
        }
        for i in 0..n {
            let x = pca.project(&data[i * dim..(i + 1) * dim], k).unwrap();
            let tol = 1e-3 * pca.eigenvalues[0].sqrt();
            for (c, xc) in x.iter().enumerate() {
                assert!((xc - pca.coords[(i, c)]).abs() < tol);
            }
            // Full-rank reconstruction round trip.
            let r = pca.reconstruct(&x).unwrap();
            let err: f32 = r
                .iter()
                .zip(&data[i * dim..(i + 1) * dim])
                .map(|(a, b)| (a - b).abs())
                .fold(0.0, f32::max);
            assert!(err < 1e-3, "round trip error {err}");
        }
    }

    #[test]
    fn eigenvalues_equal_squared_coordinate_norms_and_residuals_agree() {
        let (n, dim) = (9, 1500);
        let mut data = low_rank(n, dim, 2);
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(3);
        for v in data.iter_mut() {
            *v += rng.gen_range(-0.05..0.05);
        }
        let pca = Pca::fit(&data, n, dim, 8).unwrap();
        for c in 0..pca.components {
            let s: f64 = (0..n).map(|i| pca.coords[(i, c)].powi(2)).sum();
            assert!((s - pca.eigenvalues[c]).abs() < 1e-6 * pca.eigenvalues[0]);
        }
        // Total residual with k components = Σ_{j≥k} λ_j (eq. 2.22, without the 1/2).
        let ks = [0usize, 1, 3, 5];
        let mut tot = vec![0.0; ks.len() + 1];
        for i in 0..n {
            let r = pca.residuals(&data[i * dim..(i + 1) * dim], &ks).unwrap();
            for (t, v) in tot.iter_mut().zip(&r) {
                *t += v;
            }
        }
        for (j, &k) in ks.iter().enumerate() {
            let tail: f64 = pca.eigenvalues[k..].iter().sum();
            assert!(
                (tot[j] - tail).abs() < 1e-3 * pca.eigenvalues[0],
                "k={k}: {} vs {tail}",
                tot[j]
            );
        }
        let curve = residual_curve(&pca.eigenvalues);
        assert_eq!(curve[0], 1.0);
        assert!(curve.windows(2).all(|w| w[1] <= w[0] + 1e-12));
        assert!(curve[n] < 1e-6);
    }

    #[test]
    fn rejects_bad_input() {
        let data = low_rank(4, 100, 4);
        assert!(Pca::fit(&data, 1, 400, 2).is_err());
        let pca = Pca::fit(&data, 4, 100, 2).unwrap();
        assert!(pca.project(&data[..99], 1).is_err());
        let mut y = data[..100].to_vec();
        y[3] = f32::NAN;
        assert!(matches!(pca.project(&y, 1), Err(ReduceError::NonFinite(_))));
        assert!(pca.project(&data[..100], 3).is_err());
    }
}
