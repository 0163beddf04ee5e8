//! Locally linear embedding (Roweis & Saul; thesis §2.5.2, eqs. 2.39–2.43).

use nalgebra::{DMatrix, DVector};

use crate::error::{ReduceError, Result};
use crate::mds::{euclidean_distances, Embedding};
use crate::pca::ascending_symmetric_eigen;

/// Default regularisation of the local Gram matrices, relative to their trace.
pub const DEFAULT_REGULARISATION: f64 = 1e-3;

/// Indices of the `k` nearest neighbours of every row of `points` (excluding the row itself),
/// nearest first.
pub fn nearest_neighbours(points: &DMatrix<f64>, k: usize) -> Result<Vec<Vec<usize>>> {
    let n = points.nrows();
    if k == 0 || k >= n {
        return Err(ReduceError::InvalidParameter(format!(
            "{k} neighbours for {n} points"
        )));
    }
    let dist = euclidean_distances(points);
    Ok((0..n)
        .map(|i| {
            let mut order: Vec<usize> = (0..n).filter(|&j| j != i).collect();
            order.sort_by(|&a, &b| dist[(i, a)].total_cmp(&dist[(i, b)]).then(a.cmp(&b)));
            order.truncate(k);
            order
        })
        .collect())
}

/// Reconstruction weights `W` (`N × N`, row `i` sums to one, eqs. 2.39–2.40): each point as an
/// affine combination of its neighbours, from the local Gram matrix `C` regularised as
/// `C + reg · trace(C) · I`.
pub fn reconstruction_weights(
    points: &DMatrix<f64>,
    neighbours: &[Vec<usize>],
    reg: f64,
) -> Result<DMatrix<f64>> {
    let n = points.nrows();
    let mut w = DMatrix::zeros(n, n);
    for (i, nb) in neighbours.iter().enumerate() {
        let k = nb.len();
        let z = DMatrix::from_fn(k, points.ncols(), |a, c| {
            points[(nb[a], c)] - points[(i, c)]
        });
        let mut g = &z * z.transpose();
        let tr = g.trace();
        let r = if tr > 0.0 { reg * tr } else { reg };
        for a in 0..k {
            g[(a, a)] += r;
        }
        let sol = g
            .lu()
            .solve(&DVector::from_element(k, 1.0))
            .ok_or_else(|| {
                ReduceError::Numerical(format!("singular local Gram matrix at point {i}"))
            })?;
        let s = sol.sum();
        for (a, &j) in nb.iter().enumerate() {
            w[(i, j)] = sol[a] / s;
        }
    }
    Ok(w)
}

/// LLE embedding of the rows of `points` in `d` dimensions using `k` neighbours: the bottom
/// eigenvectors of `M = (I − W)ᵀ(I − W)` (eq. 2.42), skipping the constant one (eigenvalue 0).
/// Coordinates are the unit-norm eigenvectors; `eigenvalues` are all of `M`'s, increasing.
pub fn lle(points: &DMatrix<f64>, k: usize, d: usize, reg: f64) -> Result<Embedding> {
    let n = points.nrows();
    if d == 0 || d + 1 >= n {
        return Err(ReduceError::InvalidParameter(format!(
            "embedding dimension {d} for {n} points"
        )));
    }
    if points.iter().any(|v| !v.is_finite()) {
        return Err(ReduceError::NonFinite("LLE input"));
    }
    let nb = nearest_neighbours(points, k)?;
    let w = reconstruction_weights(points, &nb, reg)?;
    let iw = DMatrix::identity(n, n) - w;
    let m = iw.transpose() * iw;
    let (vals, vecs) = ascending_symmetric_eigen(m);
    let coords = DMatrix::from_fn(n, d, |i, c| vecs[(i, c + 1)]);
    Ok(Embedding {
        coords,
        eigenvalues: vals,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::procrustes::disparity;
    use rand::{Rng, SeedableRng};

    #[test]
    fn weights_are_affine_and_reproduce_points_in_the_plane() {
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(9);
        let pts = DMatrix::from_fn(40, 2, |_, _| rng.gen_range(0.0..1.0));
        let nb = nearest_neighbours(&pts, 5).unwrap();
        let w = reconstruction_weights(&pts, &nb, 1e-9).unwrap();
        for i in 0..40 {
            assert!((w.row(i).sum() - 1.0).abs() < 1e-9);
            // A 2-D point inside/near its 5 neighbours is reproduced almost exactly.
            let rec = w.row(i) * &pts;
            assert!((rec - pts.row(i)).norm() < 1e-4);
        }
    }

    #[test]
    fn flat_sheet_in_3d_unfolds_to_the_plane() {
        // A 2-D grid embedded linearly in 3-D: LLE recovers it up to an affine map; for this
        // isotropic grid the map is a similarity.
        let side = 12;
        let pts2 = DMatrix::from_fn(side * side, 2, |i, c| {
            if c == 0 {
                (i % side) as f64
            } else {
                (i / side) as f64
            }
        });
        let a = DMatrix::from_row_slice(2, 3, &[0.6, 0.8, 0.0, 0.0, 0.0, 1.0]);
        let pts3 = &pts2 * a;
        let e = lle(&pts3, 8, 2, DEFAULT_REGULARISATION).unwrap();
        assert!(disparity(&pts2, &e.coords).unwrap() < 0.05);
    }
}
