//! Procrustes analysis: how well one embedding matches another up to translation, rotation,
//! reflection and uniform scale.

use nalgebra::DMatrix;

use crate::error::{ReduceError, Result};

/// Procrustes disparity between two `N × d` configurations, in `[0, 1]`.
///
/// Both are centred and scaled to unit Frobenius norm; the second is then rotated (reflections
/// allowed) and scaled optimally onto the first. The result is the remaining sum of squared
/// differences, `1 − (Σ σ_k)²` where `σ_k` are the singular values of `AᵀB` (the same quantity
/// as `scipy.spatial.procrustes`).
pub fn disparity(a: &DMatrix<f64>, b: &DMatrix<f64>) -> Result<f64> {
    if a.shape() != b.shape() {
        return Err(ReduceError::Dimension {
            what: "procrustes: rows × columns of second configuration",
            expected: a.nrows() * a.ncols(),
            got: b.nrows() * b.ncols(),
        });
    }
    let na = normalise(a)?;
    let nb = normalise(b)?;
    let m = na.transpose() * nb;
    let s: f64 = m.singular_values().iter().sum();
    Ok((1.0 - s * s).max(0.0))
}

fn normalise(a: &DMatrix<f64>) -> Result<DMatrix<f64>> {
    if a.iter().any(|v| !v.is_finite()) {
        return Err(ReduceError::NonFinite("procrustes input"));
    }
    let n = a.nrows() as f64;
    let mut c = a.clone();
    for j in 0..a.ncols() {
        let m = a.column(j).sum() / n;
        c.column_mut(j).add_scalar_mut(-m);
    }
    let norm = c.norm();
    if norm == 0.0 {
        return Err(ReduceError::Numerical(
            "procrustes: configuration collapsed to a point".into(),
        ));
    }
    Ok(c / norm)
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{Rng, SeedableRng};

    #[test]
    fn invariant_to_similarity_transforms_and_sensitive_to_distortion() {
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(5);
        let a = DMatrix::from_fn(40, 2, |_, _| rng.gen_range(-1.0..1.0));
        let (c, s) = (0.3f64.cos(), 0.3f64.sin());
        let r = DMatrix::from_row_slice(2, 2, &[c, -s, s, c]);
        let mut b = &a * r * 3.5;
        b.column_mut(0).add_scalar_mut(10.0);
        b.column_mut(1).scale_mut(-1.0); // reflection
        assert!(disparity(&a, &b).unwrap() < 1e-12);
        // Anisotropic stretch is not a similarity.
        let mut d = a.clone();
        d.column_mut(0).scale_mut(3.0);
        assert!(disparity(&a, &d).unwrap() > 0.05);
    }
}
