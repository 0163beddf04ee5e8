//! Classical (metric) multidimensional scaling (thesis §2.5.1, eqs. 2.32–2.35).

use nalgebra::DMatrix;

use crate::error::{ReduceError, Result};
use crate::pca::sorted_symmetric_eigen;

/// An embedding of `N` points in `d` dimensions with the spectrum it came from.
#[derive(Debug, Clone)]
pub struct Embedding {
    /// Coordinates, `N × d` (row `i` = point `i`).
    pub coords: DMatrix<f64>,
    /// Eigenvalues of the decomposed matrix, in the order the method ranks them (all `N`).
    pub eigenvalues: Vec<f64>,
}

/// Euclidean distance matrix of the rows of `points` (`N × D`).
pub fn euclidean_distances(points: &DMatrix<f64>) -> DMatrix<f64> {
    let n = points.nrows();
    let mut d = DMatrix::zeros(n, n);
    for i in 0..n {
        for j in i + 1..n {
            let v = (points.row(i) - points.row(j)).norm();
            d[(i, j)] = v;
            d[(j, i)] = v;
        }
    }
    d
}

/// Classical MDS of a distance matrix `a` (`N × N`, symmetric, zero diagonal, finite):
/// `B = −½ H D H` with `D` the squared distances and `H = I − 1/N` (2.32–2.33), `B = V Λ Vᵀ`
/// (2.34) and `X = Λ^{1/2} V_dᵀ` (2.35). Fails when fewer than `d` positive eigenvalues exist.
pub fn classical_mds(a: &DMatrix<f64>, d: usize) -> Result<Embedding> {
    let n = a.nrows();
    ReduceError::check_size("distance matrix columns", n, a.ncols())?;
    if d == 0 || d > n {
        return Err(ReduceError::InvalidParameter(format!(
            "embedding dimension {d} for {n} points"
        )));
    }
    if a.iter().any(|v| !v.is_finite()) {
        return Err(ReduceError::NonFinite("distance matrix"));
    }
    let b = double_centre(&a.map(|v| v * v));
    let (vals, vecs) = sorted_symmetric_eigen(b);
    let tol = 1e-12 * vals[0].abs().max(f64::MIN_POSITIVE);
    if vals.iter().take(d).any(|&l| l <= tol) {
        return Err(ReduceError::Numerical(format!(
            "fewer than {d} positive eigenvalues: no {d}-dimensional Euclidean embedding"
        )));
    }
    let coords = DMatrix::from_fn(n, d, |i, c| vecs[(i, c)] * vals[c].sqrt());
    Ok(Embedding {
        coords,
        eigenvalues: vals,
    })
}

/// `−½ H D H` for a matrix of squared distances.
pub fn double_centre(sq: &DMatrix<f64>) -> DMatrix<f64> {
    let n = sq.nrows();
    let nf = n as f64;
    let row_means: Vec<f64> = (0..n).map(|i| sq.row(i).sum() / nf).collect();
    let col_means: Vec<f64> = (0..n).map(|j| sq.column(j).sum() / nf).collect();
    let all = row_means.iter().sum::<f64>() / nf;
    DMatrix::from_fn(n, n, |i, j| {
        -0.5 * (sq[(i, j)] - row_means[i] - col_means[j] + all)
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::procrustes::disparity;
    use rand::{Rng, SeedableRng};

    #[test]
    fn recovers_planar_configuration_exactly() {
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(11);
        let pts = DMatrix::from_fn(30, 2, |_, _| rng.gen_range(-5.0..5.0));
        let e = classical_mds(&euclidean_distances(&pts), 2).unwrap();
        // Distances are reproduced, so the configuration is the same up to a rigid motion.
        let d2 = euclidean_distances(&e.coords);
        assert!((d2 - euclidean_distances(&pts)).amax() < 1e-9);
        assert!(disparity(&pts, &e.coords).unwrap() < 1e-12);
        // Planar data: the third eigenvalue is zero.
        assert!(e.eigenvalues[2].abs() < 1e-9 * e.eigenvalues[0]);
    }

    #[test]
    fn rejects_non_euclidean_request() {
        let mut a = DMatrix::from_element(3, 3, 1.0);
        a.fill_diagonal(0.0);
        // Equilateral triangle: 2 positive eigenvalues, the third is 0.
        assert!(classical_mds(&a, 2).is_ok());
        assert!(classical_mds(&a, 3).is_err());
        a[(0, 1)] = f64::NAN;
        assert!(matches!(
            classical_mds(&a, 1),
            Err(ReduceError::NonFinite(_))
        ));
    }
}
