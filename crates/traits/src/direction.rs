//! Trait vectors from labels (thesis §5.1) and from graded ratings.

use nalgebra::{DMatrix, DVector};
use serde::{Deserialize, Serialize};

use crate::error::{Result, TraitsError};

/// Default shrinkage γ of the within-class scatter for Fisher's discriminant.
pub const FISHER_SHRINKAGE: f64 = 0.1;
/// Default soft-margin cost `C` of the SVM (in the scaled coordinates).
pub const SVM_COST: f64 = 10.0;
/// Ridge penalties tried (in the scaled coordinates, relative to the number of points).
pub const RIDGE_GRID: [f64; 9] = [1e-3, 3e-3, 1e-2, 3e-2, 0.1, 0.3, 1.0, 3.0, 10.0];

/// How a trait vector is computed.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Method {
    /// Mean difference (5.1).
    Mean,
    /// Regularised Fisher discriminant (5.9).
    Fisher,
    /// Soft-margin linear SVM (5.12–5.17).
    Svm,
    /// Ridge regression onto graded ratings.
    Ridge,
}

impl std::str::FromStr for Method {
    type Err = TraitsError;
    fn from_str(s: &str) -> Result<Method> {
        match s {
            "mean" => Ok(Method::Mean),
            "fisher" => Ok(Method::Fisher),
            "svm" => Ok(Method::Svm),
            "ridge" => Ok(Method::Ridge),
            o => Err(TraitsError::InvalidParameter(format!(
                "method {o:?} (mean, fisher, svm or ridge)"
            ))),
        }
    }
}

/// Tunables of the methods.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct FitOptions {
    /// Fisher shrinkage γ.
    pub fisher_shrinkage: f64,
    /// SVM cost `C`.
    pub svm_cost: f64,
    /// Fixed ridge penalty; `None` = chosen by leave-one-out from [`RIDGE_GRID`].
    pub ridge_lambda: Option<f64>,
}

impl Default for FitOptions {
    fn default() -> Self {
        FitOptions {
            fisher_shrinkage: FISHER_SHRINKAGE,
            svm_cost: SVM_COST,
            ridge_lambda: None,
        }
    }
}

/// A calibrated linear trait: score `s(x) = w·x + b`, fitted from labels (thesis §5.1) or from
/// graded ratings.
///
/// Every method turns labelled points `x_i ∈ ℝ^d` (rows of the corpus coordinates in the
/// linear or chart space) into a direction `w` and an offset `b`; the trait **score** of any
/// point is `s(x) = w·x + b`. Scores are *calibrated*: for binary labels `w` and `b` are rescaled
/// (the direction kept) so that the mean score of the materials with the trait is 1 and of
/// those without it 0; for ratings the score is the predicted rating. An edit by `a` units
/// moves a point by `a · w / ‖w‖²`, which changes its score by exactly `a`.
///
/// * [`Method::Mean`]: `w = μ₁ − μ₂` (5.1).
/// * [`Method::Fisher`]: `w = (S_W + γ·tr(S_W)/d · I)⁻¹ (μ₁ − μ₂)` (5.9). With 96 materials in
///   45 dimensions `S_W` (5.7) is poorly determined or singular, so it is shrunk towards a
///   multiple of the identity with the same trace; `γ` = `FISHER_SHRINKAGE` (0.1) by default.
///   `γ → ∞` gives back the mean difference.
/// * [`Method::Svm`]: the soft-margin support vector machine — (5.12) with slack,
///   `min ½‖w‖² + C Σ ξ_i` s.t. `y_i(w·x_i + b) ≥ 1 − ξ_i` — solved in its dual (5.16, with
///   `0 ≤ α_i ≤ C`) by exact coordinate ascent (one `α_i` at a time, clipped to the box). The
///   bias is folded in as an extra constant feature (so it is lightly regularised and the
///   equality constraint (5.15) drops out); `w = Σ α_i y_i x_i` (5.17). Points are centred on
///   the corpus mean and scaled by one overall RMS radius first (the same scale for every
///   axis, so the geometry — and the direction — is that of the original space).
/// * [`Method::Ridge`]: ratings in `[0, 1]`: `min Σ (w·x_i + b − r_i)² + λ‖w‖²` in the same
///   scaled coordinates, λ chosen from a grid by exact leave-one-out error (hat-matrix formula).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Direction {
    /// `w`.
    pub w: Vec<f64>,
    /// `b`.
    pub b: f64,
    /// Score at the decision boundary of the classifier (0.5 for mean and Fisher, the SVM's
    /// own hyperplane for the SVM, 0.5 for ratings).
    pub threshold: f64,
}

impl Direction {
    /// Score of a point.
    pub fn score(&self, x: &[f64]) -> f64 {
        self.w.iter().zip(x).map(|(a, b)| a * b).sum::<f64>() + self.b
    }

    /// The displacement that raises the score by one unit: `w / ‖w‖²`.
    pub fn unit_step(&self) -> Vec<f64> {
        let n2: f64 = self.w.iter().map(|v| v * v).sum();
        self.w.iter().map(|v| v / n2).collect()
    }

    /// Angle in degrees between two directions.
    pub fn angle_deg(&self, other: &Direction) -> f64 {
        let dot: f64 = self.w.iter().zip(&other.w).map(|(a, b)| a * b).sum();
        let na: f64 = self.w.iter().map(|v| v * v).sum::<f64>().sqrt();
        let nb: f64 = other.w.iter().map(|v| v * v).sum::<f64>().sqrt();
        (dot / (na * nb)).clamp(-1.0, 1.0).acos().to_degrees()
    }
}

/// Centre and overall RMS radius of a point set (rows), used to scale before SVM and ridge.
fn centre_scale(x: &DMatrix<f64>) -> (DVector<f64>, f64) {
    let mean = x.row_mean().transpose();
    let n = x.nrows() as f64;
    let mut ss = 0.0;
    for i in 0..x.nrows() {
        ss += (x.row(i).transpose() - &mean).norm_squared();
    }
    let r = (ss / n).sqrt();
    (mean, if r > 0.0 { r } else { 1.0 })
}

fn check_points(x: &DMatrix<f64>, n: usize) -> Result<()> {
    if x.nrows() != n {
        return Err(TraitsError::Dimension {
            what: "labels per point",
            expected: x.nrows(),
            got: n,
        });
    }
    if x.iter().any(|v| !v.is_finite()) {
        return Err(TraitsError::Numerical("non-finite coordinates".into()));
    }
    Ok(())
}

/// Fits a binary trait. `x`: `n × d` points; `y[i]`: `true` = present, `false` = absent
/// (unspecified materials are left out by the caller). `method` must not be `Ridge`.
///
/// # Examples
///
/// ```
/// use nalgebra::DMatrix;
/// use traits::{fit_binary, FitOptions, Method};
///
/// // Four materials in a 2-D space; the trait is present where the first coordinate is large.
/// let x = DMatrix::from_row_slice(4, 2, &[2.0, 0.1, 3.0, -0.2, -1.0, 0.3, -2.0, 0.0]);
/// let present = [true, true, false, false];
/// let w = fit_binary(&x, &present, Method::Svm, &FitOptions::default()).unwrap();
/// // Scores are calibrated: 1 for the average material with the trait, 0 without it.
/// assert!(w.score(&[2.5, 0.0]) > w.threshold && w.score(&[-1.5, 0.0]) < w.threshold);
/// // One unit of the trait added to a point raises its score by one.
/// let step = w.unit_step();
/// let moved = [0.0 + step[0], 0.0 + step[1]];
/// assert!((w.score(&moved) - w.score(&[0.0, 0.0]) - 1.0).abs() < 1e-9);
/// ```
pub fn fit_binary(
    x: &DMatrix<f64>,
    y: &[bool],
    method: Method,
    opts: &FitOptions,
) -> Result<Direction> {
    check_points(x, y.len())?;
    let (np, nn) = (
        y.iter().filter(|&&v| v).count(),
        y.iter().filter(|&&v| !v).count(),
    );
    if np == 0 || nn == 0 {
        return Err(TraitsError::InvalidParameter(
            "binary fit needs both classes".into(),
        ));
    }
    let d = x.ncols();
    let class_mean = |want: bool| {
        let mut m = DVector::zeros(d);
        for (i, &v) in y.iter().enumerate() {
            if v == want {
                m += x.row(i).transpose();
            }
        }
        m / if want { np as f64 } else { nn as f64 }
    };
    let (mu1, mu2) = (class_mean(true), class_mean(false));
    let (w, svm_b) = match method {
        Method::Mean => (&mu1 - &mu2, None),
        Method::Fisher => {
            let mut sw = DMatrix::zeros(d, d);
            for (i, &v) in y.iter().enumerate() {
                let c = x.row(i).transpose() - if v { &mu1 } else { &mu2 };
                sw += &c * c.transpose();
            }
            let shrink = opts.fisher_shrinkage * sw.trace() / d as f64;
            let shrink = if shrink > 0.0 { shrink } else { 1e-12 };
            for k in 0..d {
                sw[(k, k)] += shrink;
            }
            let chol = sw
                .cholesky()
                .ok_or_else(|| TraitsError::Numerical("Fisher scatter not positive".into()))?;
            (chol.solve(&(&mu1 - &mu2)), None)
        }
        Method::Svm => {
            let (c, s) = centre_scale(x);
            let z = DMatrix::from_fn(x.nrows(), d, |i, k| (x[(i, k)] - c[k]) / s);
            let labels: Vec<f64> = y.iter().map(|&v| if v { 1.0 } else { -1.0 }).collect();
            let (wz, bz) = svm_dual_cd(&z, &labels, opts.svm_cost)?;
            // w·(x − c)/s + bz = (w/s)·x + (bz − w·c/s).
            let w = wz / s;
            let b = bz - w.dot(&c);
            (w, Some(b))
        }
        Method::Ridge => {
            return Err(TraitsError::InvalidParameter(
                "ridge regression needs ratings, not binary labels".into(),
            ))
        }
    };
    if w.norm() == 0.0 || !w.norm().is_finite() {
        return Err(TraitsError::Numerical("zero trait direction".into()));
    }
    // Calibrate: mean score of the present class 1, of the absent class 0.
    let (p1, p2) = (w.dot(&mu1), w.dot(&mu2));
    if p1 - p2 <= 0.0 {
        return Err(TraitsError::Numerical(
            "trait direction does not separate the class means".into(),
        ));
    }
    let scale = 1.0 / (p1 - p2);
    let b = -p2 * scale;
    let threshold = match svm_b {
        // The SVM's boundary w·x + b_svm = 0 in calibrated units.
        Some(bs) => -bs * scale + b,
        None => 0.5,
    };
    Ok(Direction {
        w: (w * scale).iter().copied().collect(),
        b,
        threshold,
    })
}

/// Soft-margin linear SVM by dual coordinate ascent with the bias as a constant feature:
/// maximise `Σα − ½ Σ α_i α_j y_i y_j (z_i·z_j + 1)` over `0 ≤ α ≤ C`. Returns `(w, b)`.
fn svm_dual_cd(z: &DMatrix<f64>, y: &[f64], cost: f64) -> Result<(DVector<f64>, f64)> {
    if cost.is_nan() || cost <= 0.0 {
        return Err(TraitsError::InvalidParameter(format!("SVM cost {cost}")));
    }
    let (n, d) = z.shape();
    let q: Vec<f64> = (0..n).map(|i| z.row(i).norm_squared() + 1.0).collect();
    let mut alpha = vec![0.0; n];
    let mut w = DVector::<f64>::zeros(d);
    let mut b = 0.0;
    for _sweep in 0..2000 {
        let mut max_change: f64 = 0.0;
        for i in 0..n {
            let zi = z.row(i).transpose();
            let g = y[i] * (w.dot(&zi) + b) - 1.0;
            let new = (alpha[i] - g / q[i]).clamp(0.0, cost);
            let delta = new - alpha[i];
            if delta != 0.0 {
                w += &zi * (delta * y[i]);
                b += delta * y[i];
                alpha[i] = new;
                max_change = max_change.max(delta.abs() * q[i].sqrt());
            }
        }
        if max_change < 1e-9 {
            break;
        }
    }
    Ok((w, b))
}

/// Fits a graded trait by ridge regression; `r[i]` is the rating of row `i`.
/// Returns the direction and the λ used.
pub fn fit_ridge(x: &DMatrix<f64>, r: &[f64], opts: &FitOptions) -> Result<(Direction, f64)> {
    check_points(x, r.len())?;
    let n = x.nrows();
    if n < 3 {
        return Err(TraitsError::InvalidParameter(
            "ridge needs at least 3 ratings".into(),
        ));
    }
    let (c, s) = centre_scale(x);
    let d = x.ncols();
    let z = DMatrix::from_fn(n, d, |i, k| (x[(i, k)] - c[k]) / s);
    let rbar = r.iter().sum::<f64>() / n as f64;
    let t = DVector::from_iterator(n, r.iter().map(|v| v - rbar));
    // Kernel form (n ≤ d is common): K = Z Zᵀ, ŷ = K (K + λI)⁻¹ t.
    let k = &z * z.transpose();
    let eig = k.clone().symmetric_eigen();
    let loo = |lam: f64| -> f64 {
        // H = K (K + λI)⁻¹ with the centring folded in (intercept = mean): LOO residual
        // e_i / (1 − H_ii − 1/n).
        let mut h = DMatrix::zeros(n, n);
        for j in 0..n {
            let l = eig.eigenvalues[j].max(0.0);
            let f = l / (l + lam);
            let v = eig.eigenvectors.column(j);
            h += v * v.transpose() * f;
        }
        let fit = &h * &t;
        (0..n)
            .map(|i| {
                let e = t[i] - fit[i];
                let den = 1.0 - h[(i, i)] - 1.0 / n as f64;
                (e / den.max(1e-9)).powi(2)
            })
            .sum()
    };
    let lam = match opts.ridge_lambda {
        Some(l) if l > 0.0 => l,
        Some(l) => return Err(TraitsError::InvalidParameter(format!("ridge λ {l}"))),
        None => RIDGE_GRID
            .iter()
            .map(|&g| g * n as f64)
            .min_by(|a, b| loo(*a).total_cmp(&loo(*b)))
            .unwrap_or(1.0),
    };
    let mut kk = k;
    for i in 0..n {
        kk[(i, i)] += lam;
    }
    let a = kk
        .cholesky()
        .ok_or_else(|| TraitsError::Numerical("ridge system not positive".into()))?
        .solve(&t);
    let wz = z.transpose() * a;
    let w = wz / s;
    let b = rbar - w.dot(&c);
    Ok((
        Direction {
            w: w.iter().copied().collect(),
            b,
            threshold: 0.5,
        },
        lam,
    ))
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{Rng, SeedableRng};

    /// Two Gaussian classes separated along a known axis, with a large nuisance variance along
    /// another axis.
    fn classes(n: usize, seed: u64) -> (DMatrix<f64>, Vec<bool>) {
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed);
        let mut x = DMatrix::zeros(n, 4);
        let mut y = Vec::new();
        for i in 0..n {
            let c = i % 2 == 0;
            y.push(c);
            x[(i, 0)] = if c { 1.5 } else { -1.5 } + rng.gen_range(-1.0..1.0);
            x[(i, 1)] = 20.0 * rng.gen_range(-1.0..1.0);
            // Correlated nuisance: axis 2 copies axis 1 up to noise.
            x[(i, 2)] = x[(i, 1)] + rng.gen_range(-0.5..0.5) + if c { 0.3 } else { -0.3 };
            x[(i, 3)] = rng.gen_range(-1.0..1.0);
        }
        (x, y)
    }

    #[test]
    fn all_binary_methods_separate_and_are_calibrated() {
        let (x, y) = classes(80, 3);
        for m in [Method::Mean, Method::Fisher, Method::Svm] {
            let d = fit_binary(&x, &y, m, &FitOptions::default()).unwrap();
            let scores: Vec<f64> = (0..x.nrows())
                .map(|i| d.score(x.row(i).transpose().as_slice()))
                .collect();
            let mean = |c: bool| {
                let v: Vec<f64> = scores
                    .iter()
                    .zip(&y)
                    .filter(|(_, &l)| l == c)
                    .map(|(s, _)| *s)
                    .collect();
                v.iter().sum::<f64>() / v.len() as f64
            };
            assert!((mean(true) - 1.0).abs() < 1e-9, "{m:?}");
            assert!(mean(false).abs() < 1e-9, "{m:?}");
            // A unit step raises the score by exactly one.
            let x0 = x.row(0).transpose();
            let x1: Vec<f64> = x0.iter().zip(d.unit_step()).map(|(a, b)| a + b).collect();
            assert!((d.score(&x1) - d.score(x0.as_slice()) - 1.0).abs() < 1e-9);
            let acc = scores
                .iter()
                .zip(&y)
                .filter(|(s, &l)| (**s > d.threshold) == l)
                .count() as f64
                / y.len() as f64;
            // The mean difference is misled by the correlated nuisance axes; the others are not.
            let want = if m == Method::Mean { 0.6 } else { 0.9 };
            assert!(acc >= want, "{m:?}: training accuracy {acc}");
        }
    }

    #[test]
    fn svm_finds_the_max_margin_hyperplane_of_separable_points() {
        // Points at x = ±1 (support vectors) and further out: the optimal normal is the x axis,
        // whatever the spread along y.
        let pts = [
            (1.0, 0.0),
            (1.0, 3.0),
            (2.5, -2.0),
            (3.0, 1.0),
            (-1.0, 1.0),
            (-1.0, -3.0),
            (-2.0, 2.0),
            (-4.0, 0.5),
        ];
        let x = DMatrix::from_fn(
            pts.len(),
            2,
            |i, k| if k == 0 { pts[i].0 } else { pts[i].1 },
        );
        let y: Vec<bool> = pts.iter().map(|p| p.0 > 0.0).collect();
        let opts = FitOptions {
            svm_cost: 1e4,
            ..Default::default()
        };
        let d = fit_binary(&x, &y, Method::Svm, &opts).unwrap();
        let angle = d.w[1].atan2(d.w[0]).to_degrees().abs();
        assert!(angle < 3.0, "normal off the x axis by {angle}°: {:?}", d.w);
        // The boundary sits midway between x = −1 and x = 1 (up to the regularised bias).
        let b0 = (d.threshold - d.b) / d.w[0];
        assert!(b0.abs() < 0.1, "boundary at x = {b0}");
    }

    #[test]
    fn ridge_recovers_a_linear_rating() {
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(9);
        let n = 60;
        let x = DMatrix::from_fn(n, 5, |_, _| rng.gen_range(-1.0..1.0));
        let r: Vec<f64> = (0..n)
            .map(|i| 0.5 + 0.2 * x[(i, 0)] - 0.1 * x[(i, 3)])
            .collect();
        let (d, lam) = fit_ridge(&x, &r, &FitOptions::default()).unwrap();
        assert!(lam <= 0.1 * n as f64, "λ = {lam}");
        for i in 0..n {
            let s = d.score(x.row(i).transpose().as_slice());
            assert!((s - r[i]).abs() < 0.03, "{s} vs {}", r[i]);
        }
        assert!(fit_binary(&x, &vec![true; n], Method::Mean, &FitOptions::default()).is_err());
    }
}
