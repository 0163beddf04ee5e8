//! Fitting whole trait sets and measuring how well each trait is determined.
//!
//! * Binary traits: leave-one-out accuracy of the sign of the score (the held-out material's
//!   score against the classifier's threshold, the trait refitted without it).
//! * Rated traits: leave-one-out Spearman ρ between each held-out material's predicted score
//!   and its human rating.
//! * The angle between the directions of two methods for the same trait.

use nalgebra::DMatrix;

use crate::direction::{fit_binary, fit_ridge, Direction, FitOptions, Method};
use crate::error::{Result, TraitsError};
use crate::labels::{Label, LabelSet, RatingSet};
use crate::navigate::{Space, TraitSet, TraitVector};

/// Rows of `coords` (named by `names`) with a label for trait `t`, and the labels.
pub fn labelled_rows(
    coords: &DMatrix<f64>,
    names: &[String],
    labels: &LabelSet,
    t: usize,
) -> Result<(DMatrix<f64>, Vec<bool>)> {
    let mut rows = Vec::new();
    let mut y = Vec::new();
    for (m, l) in labels.column(t) {
        if l == Label::Unspecified {
            continue;
        }
        let i = names
            .iter()
            .position(|n| n == m)
            .ok_or_else(|| TraitsError::UnknownMaterial(m.into()))?;
        rows.push(i);
        y.push(l == Label::Present);
    }
    Ok((coords.select_rows(&rows), y))
}

/// Rows of `coords` with a rating for trait `t`, and the ratings.
pub fn rated_rows(
    coords: &DMatrix<f64>,
    names: &[String],
    ratings: &RatingSet,
    t: usize,
) -> Result<(DMatrix<f64>, Vec<f64>)> {
    let mut rows = Vec::new();
    let mut r = Vec::new();
    for (m, v) in ratings.column(t) {
        let Some(v) = v else { continue };
        let i = names
            .iter()
            .position(|n| n == m)
            .ok_or_else(|| TraitsError::UnknownMaterial(m.into()))?;
        rows.push(i);
        r.push(v);
    }
    Ok((coords.select_rows(&rows), r))
}

/// Leave-one-out accuracy of the sign of the score of a binary method.
pub fn loo_sign_accuracy(
    x: &DMatrix<f64>,
    y: &[bool],
    method: Method,
    opts: &FitOptions,
) -> Result<f64> {
    let n = x.nrows();
    let mut right = 0;
    for i in 0..n {
        let xi = x.clone().remove_row(i);
        let mut yi = y.to_vec();
        yi.remove(i);
        let d = fit_binary(&xi, &yi, method, opts)?;
        let s = d.score(x.row(i).transpose().as_slice());
        if (s > d.threshold) == y[i] {
            right += 1;
        }
    }
    Ok(right as f64 / n as f64)
}

/// Leave-one-out predictions of ridge regression (λ chosen again inside every fold).
pub fn loo_ridge_predictions(x: &DMatrix<f64>, r: &[f64], opts: &FitOptions) -> Result<Vec<f64>> {
    (0..x.nrows())
        .map(|i| {
            let xi = x.clone().remove_row(i);
            let mut ri = r.to_vec();
            ri.remove(i);
            let (d, _) = fit_ridge(&xi, &ri, opts)?;
            Ok(d.score(x.row(i).transpose().as_slice()))
        })
        .collect()
}

/// Spearman's rank correlation (average ranks for ties).
pub fn spearman(a: &[f64], b: &[f64]) -> f64 {
    fn ranks(v: &[f64]) -> Vec<f64> {
        let mut idx: Vec<usize> = (0..v.len()).collect();
        idx.sort_by(|&i, &j| v[i].total_cmp(&v[j]));
        let mut r = vec![0.0; v.len()];
        let mut i = 0;
        while i < idx.len() {
            let mut j = i;
            while j + 1 < idx.len() && v[idx[j + 1]] == v[idx[i]] {
                j += 1;
            }
            let avg = (i + j) as f64 / 2.0 + 1.0;
            for k in i..=j {
                r[idx[k]] = avg;
            }
            i = j + 1;
        }
        r
    }
    let (ra, rb) = (ranks(a), ranks(b));
    let n = a.len() as f64;
    let (ma, mb) = (ra.iter().sum::<f64>() / n, rb.iter().sum::<f64>() / n);
    let (mut sab, mut saa, mut sbb) = (0.0, 0.0, 0.0);
    for (x, y) in ra.iter().zip(&rb) {
        sab += (x - ma) * (y - mb);
        saa += (x - ma).powi(2);
        sbb += (y - mb).powi(2);
    }
    if saa == 0.0 || sbb == 0.0 {
        0.0
    } else {
        sab / (saa * sbb).sqrt()
    }
}

/// Fits every trait of a label set (binary methods) or rating set (ridge) on the corpus
/// coordinates of a space; `cross_validate` adds the leave-one-out agreement to each trait.
pub struct SetFit<'a> {
    /// Corpus coordinates in the space (`N × d`).
    pub coords: &'a DMatrix<f64>,
    /// Corpus names (rows of `coords`).
    pub names: &'a [String],
    /// The space.
    pub space: Space,
    /// Method tunables.
    pub options: FitOptions,
    /// Whether to measure leave-one-out agreement.
    pub cross_validate: bool,
}

impl SetFit<'_> {
    /// Binary traits of a label set with `method` (mean, Fisher or SVM).
    pub fn binary(&self, labels: &LabelSet, method: Method) -> Result<TraitSet> {
        labels.check(self.names)?;
        let traits = (0..labels.traits.len())
            .map(|t| {
                let (x, y) = labelled_rows(self.coords, self.names, labels, t)?;
                let direction = fit_binary(&x, &y, method, &self.options)?;
                let cv = if self.cross_validate {
                    Some(loo_sign_accuracy(&x, &y, method, &self.options)?)
                } else {
                    None
                };
                Ok(TraitVector {
                    name: labels.traits[t].clone(),
                    direction,
                    cross_validated: cv,
                })
            })
            .collect::<Result<Vec<_>>>()?;
        Ok(TraitSet {
            space: self.space,
            dim: self.coords.ncols(),
            method,
            traits,
        })
    }

    /// Graded traits of a rating set by ridge regression.
    pub fn ratings(&self, ratings: &RatingSet) -> Result<TraitSet> {
        ratings.check(self.names, 5)?;
        let traits = (0..ratings.traits.len())
            .map(|t| {
                let (x, r) = rated_rows(self.coords, self.names, ratings, t)?;
                let (direction, _) = fit_ridge(&x, &r, &self.options)?;
                let cv = if self.cross_validate {
                    Some(spearman(&loo_ridge_predictions(&x, &r, &self.options)?, &r))
                } else {
                    None
                };
                Ok(TraitVector {
                    name: ratings.traits[t].clone(),
                    direction,
                    cross_validated: cv,
                })
            })
            .collect::<Result<Vec<_>>>()?;
        Ok(TraitSet {
            space: self.space,
            dim: self.coords.ncols(),
            method: Method::Ridge,
            traits,
        })
    }
}

/// Angles (degrees) between the directions of the same trait in two sets.
pub fn angles(a: &TraitSet, b: &TraitSet) -> Vec<(String, f64)> {
    a.traits
        .iter()
        .filter_map(|t| {
            b.get(&t.name).ok().map(|u| {
                (
                    t.name.clone(),
                    Direction::angle_deg(&t.direction, &u.direction),
                )
            })
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn spearman_of_monotone_and_reversed_sequences() {
        let a = [1.0, 2.0, 3.0, 4.0, 5.0];
        let b = [0.1, 0.5, 0.7, 10.0, 11.0];
        assert!((spearman(&a, &b) - 1.0).abs() < 1e-12);
        let c: Vec<f64> = b.iter().rev().copied().collect();
        assert!((spearman(&a, &c) + 1.0).abs() < 1e-12);
        // Ties: scipy.stats.spearmanr([1,2,2,3],[1,3,2,4]) = 0.9486832980505138.
        let r = spearman(&[1.0, 2.0, 2.0, 3.0], &[1.0, 3.0, 2.0, 4.0]);
        assert!((r - 0.948_683_298_050_513_8).abs() < 1e-12, "{r}");
    }
}
