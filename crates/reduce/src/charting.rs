//! Manifold charting (Brand 2003; thesis §2.5.2 and §4.4, eqs. 2.44–2.55).

use nalgebra::{DMatrix, DVector};

use crate::error::{ReduceError, Result};
use crate::mds::euclidean_distances;
use crate::pca::sorted_symmetric_eigen;

/// Tunables of the charting step.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ChartingConfig {
    /// Kernel width; `None` = half the mean nearest-neighbour distance (the thesis's default).
    pub sigma: Option<f64>,
    /// Chart covariance eigenvalues are floored at this fraction of the chart's largest one
    /// before evaluating Gaussian densities.
    pub eigen_floor: f64,
    /// Chart posteriors `p_{k|y}` use `Σ_k + broadening · σ² I` instead of `Σ_k`: the chart
    /// centre is only known to within the co-locality width σ (2.47). Without it (0.0) the
    /// MAP covariances are so thin across the manifold that every point belongs almost only to
    /// its own chart and the charts cannot be connected.
    pub posterior_broadening: f64,
    /// Singular values of `A_k` below this fraction of the largest are treated as zero in the
    /// pseudo-inverse of the back-projection (2.54).
    pub pinv_tolerance: f64,
    /// Relative ridge added to the `(d+1) × (d+1)` blocks of `D` and to the embedding-space
    /// covariances of (2.55), as a fraction of their mean diagonal.
    pub ridge: f64,
}

impl Default for ChartingConfig {
    fn default() -> Self {
        ChartingConfig {
            sigma: None,
            eigen_floor: 1e-6,
            posterior_broadening: 1.0,
            pinv_tolerance: 1e-12,
            ridge: 1e-9,
        }
    }
}

/// The dimension-independent part of manifold charting (Brand 2003; thesis §2.5.2 and §4.4,
/// eqs. 2.44–2.55): one Gaussian chart per point, which [`Charts::connect`] joins into a
/// [`Chart`] of a chosen dimension.
///
/// Input points are rows of an `N × K` matrix (in practice the PCA coordinates of the corpus,
/// not the 4.37 M-dimensional log vectors). One chart is centred on every point (`μ_i = y_i`,
/// equal priors); the co-locality kernel is `m_i(μ_j) ∝ exp(−‖μ_j − μ_i‖² / 2σ²)` with `σ` half
/// the mean nearest-neighbour distance (2.47).
///
/// **Covariances (eq. 2.48).** Taken literally, (2.48) averages `Σ_j` with weights summing to one,
/// which makes the linear system singular (adding any common matrix to all `Σ_i` keeps it
/// satisfied while the data term keeps growing). Writing out the stationarity condition of the
/// posterior (2.46) with the data likelihood and the cross-entropy prior weighted by the same
/// kernel gives the same terms with the normaliser counting both, i.e. for every chart `i`
///
/// `(a_i + b_i) Σ_i − Σ_{j≠i} m_ij Σ_j = Σ_j m_ij [(y_j − μ_i)(y_j − μ_i)ᵀ + (μ_j − μ_i)(μ_j − μ_i)ᵀ]`
///
/// with `a_i = Σ_j m_ij` (data weights, `j = i` included) and `b_i = Σ_{j≠i} m_ij` (prior
/// weights). The `N × N` system matrix is symmetric and strictly diagonally dominant, so it is
/// solved exactly (Cholesky) for all `K²` covariance entries at once.
///
/// **Charts (2.49–2.51).** `Σ_k = V_k Λ_k V_kᵀ`; `W_k` is the first `d` rows of `V_kᵀ`; local
/// coordinates `u_ki = W_k (y_i − μ_k)`. Chart posteriors `p_{k|y}` are the normalised Gaussian
/// densities `N(y; μ_k, Σ_k)` (eigenvalues floored at `eigen_floor · λ_max` for stability).
///
/// **Connection (2.53).** With `z_ki = [u_ki; 1]`, `q_i = [p_1i z_1i; …; p_Ni z_Ni]` and
/// `D = blockdiag_k Σ_i p_ki z_ki z_kiᵀ`, the objective (2.53) equals `2 tr Γᵀ (D − QQᵀ) Γ`
/// where `Γ` stacks the `G_kᵀ`. Under the normalisation `Γᵀ D Γ = I` the minimisers are the top
/// generalised eigenvectors of `QQᵀ γ = μ D γ` after the trivial one (`μ = 1`, a constant
/// embedding). Because `QQᵀ` has rank ≤ N this is solved through the `N × N` matrix
/// `M = Qᵀ D⁻¹ Q` (`M w = μ w`, `γ = D⁻¹ Q w / √μ`), which is small whatever `K` and `d` are.
/// The embedding of point `i` is then `x_i = Γᵀ q_i` — exactly the forward map (2.52).
///
/// **Back-projection (2.54–2.55).** `ŷ(x) = Σ_k p_{k|x} (μ_k + W_kᵀ A_k⁺ (x − c_k))` with
/// `G_k = [A_k, c_k]` and `p_{k|x} ∝ N(x; c_k, A_k Λ_k^{(d)} A_kᵀ)`.
///
/// # Examples
///
/// ```
/// use nalgebra::DMatrix;
/// use reduce::{ChartingConfig, Charts};
///
/// // 16 points on a gently curved line in 3 dimensions
/// let points = DMatrix::from_fn(16, 3, |i, j| {
///     let t = i as f64 / 15.0;
///     [t, 0.3 * t * t, 0.1 * (2.0 * t).sin()][j]
/// });
/// let charts = Charts::fit(&points, ChartingConfig::default()).unwrap();
/// assert_eq!((charts.len(), charts.ambient_dim()), (16, 3));
/// // connected into one coordinate along the curve
/// let chart = charts.connect(1).unwrap();
/// assert_eq!(chart.embedding().unwrap().shape(), (16, 1));
/// assert!(chart.reconstruction_error().unwrap() < 0.2);
/// ```
#[derive(Debug, Clone)]
pub struct Charts {
    /// Chart centres `μ_k` (`N × K`, equal to the input points).
    pub centres: DMatrix<f64>,
    /// Kernel width σ used for (2.47).
    pub sigma: f64,
    /// Per chart: eigenvectors of `Σ_k` as columns, by decreasing eigenvalue (2.49).
    pub eigenvectors: Vec<DMatrix<f64>>,
    /// Per chart: eigenvalues of `Σ_k`, decreasing, floored and broadened by
    /// `posterior_broadening · σ²` (see [`ChartingConfig`]); these define `p_{k|y}` and `Λ_k`.
    pub eigenvalues: Vec<Vec<f64>>,
    /// Configuration used.
    pub config: ChartingConfig,
}

/// Half the mean distance from each point to its nearest neighbour.
pub fn default_sigma(points: &DMatrix<f64>) -> Result<f64> {
    let n = points.nrows();
    if n < 2 {
        return Err(ReduceError::NotEnoughData(
            "charting needs at least 2 points".into(),
        ));
    }
    let d = euclidean_distances(points);
    let mean_nn = (0..n)
        .map(|i| {
            (0..n)
                .filter(|&j| j != i)
                .map(|j| d[(i, j)])
                .fold(f64::INFINITY, f64::min)
        })
        .sum::<f64>()
        / n as f64;
    Ok(0.5 * mean_nn)
}

impl Charts {
    /// Fits one chart per row of `points` (MAP covariances, eq. 2.48, solved exactly).
    pub fn fit(points: &DMatrix<f64>, config: ChartingConfig) -> Result<Charts> {
        let (n, k) = points.shape();
        if points.iter().any(|v| !v.is_finite()) {
            return Err(ReduceError::NonFinite("charting input"));
        }
        let sigma = match config.sigma {
            Some(s) if s > 0.0 && s.is_finite() => s,
            Some(s) => return Err(ReduceError::InvalidParameter(format!("sigma = {s}"))),
            None => default_sigma(points)?,
        };
        if sigma.is_nan() || sigma <= 0.0 {
            return Err(ReduceError::NotEnoughData(
                "duplicate points: zero nearest-neighbour distance".into(),
            ));
        }
        let d = euclidean_distances(points);
        let w = d.map(|v| (-(v * v) / (2.0 * sigma * sigma)).exp());
        // System matrix: diag(a + b) − W₀.
        let mut sys = DMatrix::zeros(n, n);
        for i in 0..n {
            let a: f64 = w.row(i).sum();
            let b = a - w[(i, i)];
            sys[(i, i)] = a + b;
            for j in 0..n {
                if j != i {
                    sys[(i, j)] = -w[(i, j)];
                }
            }
        }
        // Right-hand sides: 2 Σ_j m_ij Δ_ij Δ_ijᵀ, one row of K² entries per chart.
        let mut rhs = DMatrix::zeros(n, k * k);
        for i in 0..n {
            let delta = DMatrix::from_fn(n, k, |j, c| {
                (points[(j, c)] - points[(i, c)]) * w[(i, j)].sqrt()
            });
            let s = delta.transpose() * delta * 2.0;
            for (e, v) in s.iter().enumerate() {
                rhs[(i, e)] = *v;
            }
        }
        let chol = sys.cholesky().ok_or_else(|| {
            ReduceError::Numerical("charting covariance system is not positive definite".into())
        })?;
        let cov = chol.solve(&rhs);
        let mut eigenvectors = Vec::with_capacity(n);
        let mut eigenvalues = Vec::with_capacity(n);
        for i in 0..n {
            let s = DMatrix::from_iterator(k, k, cov.row(i).iter().copied());
            let s = (&s + s.transpose()) * 0.5;
            let (mut vals, vecs) = sorted_symmetric_eigen(s);
            let floor = vals[0].max(f64::MIN_POSITIVE) * config.eigen_floor;
            let broaden = config.posterior_broadening * sigma * sigma;
            for v in vals.iter_mut() {
                *v = v.max(floor) + broaden;
            }
            eigenvalues.push(vals);
            eigenvectors.push(vecs);
        }
        Ok(Charts {
            centres: points.clone(),
            sigma,
            eigenvectors,
            eigenvalues,
            config,
        })
    }

    /// Number of charts.
    pub fn len(&self) -> usize {
        self.centres.nrows()
    }

    /// Whether there are no charts.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// Ambient dimension `K`.
    pub fn ambient_dim(&self) -> usize {
        self.centres.ncols()
    }

    /// Chart posteriors `p_{k|y}(y)` (normalised Gaussian densities, equal priors).
    pub fn posteriors(&self, y: &DVector<f64>) -> Result<Vec<f64>> {
        ReduceError::check_size("point dimension", self.ambient_dim(), y.len())?;
        if y.iter().any(|v| !v.is_finite()) {
            return Err(ReduceError::NonFinite("point to chart"));
        }
        let logs: Vec<f64> = (0..self.len())
            .map(|c| {
                let diff = y - self.centres.row(c).transpose();
                let proj = self.eigenvectors[c].tr_mul(&diff);
                let vals = &self.eigenvalues[c];
                -0.5 * proj
                    .iter()
                    .zip(vals)
                    .map(|(p, l)| p * p / l + l.ln())
                    .sum::<f64>()
            })
            .collect();
        Ok(softmax(&logs))
    }

    /// Local coordinates `u_k = W_k (y − μ_k)` of `y` in chart `k` for dimension `d` (2.51).
    pub fn local_coords(&self, k: usize, d: usize, y: &DVector<f64>) -> DVector<f64> {
        let diff = y - self.centres.row(k).transpose();
        self.eigenvectors[k].columns(0, d).tr_mul(&diff)
    }

    /// Connects the charts into a `d`-dimensional global coordinate system (2.53).
    pub fn connect(&self, d: usize) -> Result<Chart> {
        let n = self.len();
        if d == 0 || d > self.ambient_dim() || d + 1 >= n {
            return Err(ReduceError::InvalidParameter(format!(
                "embedding dimension {d} for {n} charts in {} dimensions",
                self.ambient_dim()
            )));
        }
        let posts: Vec<Vec<f64>> = (0..n)
            .map(|i| self.posteriors(&self.centres.row(i).transpose()))
            .collect::<Result<_>>()?;
        let m1 = d + 1;
        // z[k][i] = [u_ki; 1] for points with non-negligible posterior in chart k.
        let mut z: Vec<Vec<(usize, DVector<f64>)>> = vec![Vec::new(); n];
        for (i, p) in posts.iter().enumerate() {
            let y = self.centres.row(i).transpose();
            for (k, &pk) in p.iter().enumerate() {
                if pk > 1e-14 {
                    let u = self.local_coords(k, d, &y);
                    let mut zz = DVector::from_element(m1, 1.0);
                    zz.rows_mut(0, d).copy_from(&u);
                    z[k].push((i, zz));
                }
            }
        }
        // D_k⁻¹ blocks.
        let mut dinv = Vec::with_capacity(n);
        for (k, zk) in z.iter().enumerate() {
            let mut dk = DMatrix::zeros(m1, m1);
            for (i, zz) in zk {
                dk += zz * zz.transpose() * posts[*i][k];
            }
            let ridge = self.config.ridge * (dk.trace() / m1 as f64).max(f64::MIN_POSITIVE);
            for a in 0..m1 {
                dk[(a, a)] += ridge;
            }
            let inv = dk
                .cholesky()
                .ok_or_else(|| {
                    ReduceError::Numerical(format!("chart {k}: singular weighted scatter"))
                })?
                .inverse();
            dinv.push(inv);
        }
        // M = Qᵀ D⁻¹ Q.
        let mut m = DMatrix::zeros(n, n);
        for (k, zk) in z.iter().enumerate() {
            let t: Vec<DVector<f64>> = zk
                .iter()
                .map(|(i, zz)| &dinv[k] * zz * posts[*i][k])
                .collect();
            for (a, (i, zi)) in zk.iter().enumerate() {
                let pi = posts[*i][k];
                for (j, _) in zk.iter().skip(a).enumerate() {
                    let (jj, _) = zk[a + j];
                    let v = pi * zi.dot(&t[a + j]);
                    m[(*i, jj)] += v;
                    if jj != *i {
                        m[(jj, *i)] += v;
                    }
                }
            }
        }
        let (mu, w) = sorted_symmetric_eigen(m);
        // Skip the trivial (constant) solution: the eigenvector most aligned with 1.
        let ones = DVector::from_element(n, 1.0 / (n as f64).sqrt());
        let trivial = (0..n.min(d + 2))
            .max_by(|&a, &b| {
                w.column(a)
                    .dot(&ones)
                    .abs()
                    .total_cmp(&w.column(b).dot(&ones).abs())
            })
            .unwrap_or(0);
        let chosen: Vec<usize> = (0..n).filter(|&c| c != trivial).take(d).collect();
        if chosen.iter().any(|&c| mu[c].is_nan() || mu[c] <= 0.0) {
            return Err(ReduceError::Numerical(format!(
                "charting: fewer than {d} non-trivial directions"
            )));
        }
        // G_k rows: γ_c restricted to chart k, γ_c = D⁻¹ Q w_c / √μ_c.
        let mut maps = vec![DMatrix::zeros(d, m1); n];
        for (k, zk) in z.iter().enumerate() {
            for (row, &c) in chosen.iter().enumerate() {
                let mut g = DVector::zeros(m1);
                for (i, zz) in zk {
                    g += zz * (posts[*i][k] * w[(*i, c)]);
                }
                let g = &dinv[k] * g / mu[c].sqrt();
                maps[k].row_mut(row).copy_from(&g.transpose());
            }
        }
        let spectrum: Vec<f64> = chosen.iter().map(|&c| mu[c]).collect();
        Chart::new(self.clone(), d, maps, spectrum)
    }
}

fn softmax(logs: &[f64]) -> Vec<f64> {
    let mx = logs.iter().copied().fold(f64::NEG_INFINITY, f64::max);
    let e: Vec<f64> = logs.iter().map(|l| (l - mx).exp()).collect();
    let s: f64 = e.iter().sum();
    e.iter().map(|v| v / s).collect()
}

/// A connected `d`-dimensional chart of the data: forward map (2.52) and back-projection
/// (2.54–2.55), made by [`Charts::connect`] (whose docs give the method and an example).
///
/// # Examples
///
/// ```
/// use nalgebra::{DMatrix, DVector};
/// use reduce::{ChartingConfig, Charts};
///
/// // 12 points on a straight line in the plane: a 1-dimensional chart maps them and back
/// let points = DMatrix::from_fn(12, 2, |i, j| [i as f64, 0.5 * i as f64][j]);
/// let chart = Charts::fit(&points, ChartingConfig::default()).unwrap().connect(1).unwrap();
/// let y = DVector::from_vec(vec![4.0, 2.0]);
/// let x = chart.forward(&y).unwrap();
/// assert_eq!(x.len(), 1);
/// assert!((chart.backward(&x).unwrap() - y).norm() < 0.1);
/// ```
#[derive(Debug, Clone)]
pub struct Chart {
    /// The per-point charts.
    pub charts: Charts,
    /// Embedding dimension `d`.
    pub dim: usize,
    /// Affine maps `G_k` (`d × (d+1)`), one per chart.
    pub maps: Vec<DMatrix<f64>>,
    /// Generalised eigenvalues `μ` of the chosen directions (1 = perfect agreement of charts).
    pub spectrum: Vec<f64>,
    /// Derived: pseudo-inverses `A_k⁺`.
    pinv: Vec<DMatrix<f64>>,
    /// Derived: inverse covariance and log-determinant of `N(x; c_k, A_k Λ A_kᵀ)`.
    x_gauss: Vec<(DMatrix<f64>, f64)>,
}

impl Chart {
    /// Assembles a chart from its parameters (also used when loading a model file).
    pub fn new(
        charts: Charts,
        dim: usize,
        maps: Vec<DMatrix<f64>>,
        spectrum: Vec<f64>,
    ) -> Result<Chart> {
        if maps.len() != charts.len() || maps.iter().any(|g| g.shape() != (dim, dim + 1)) {
            return Err(ReduceError::Dimension {
                what: "chart maps (one d × (d+1) per chart)",
                expected: charts.len(),
                got: maps.len(),
            });
        }
        let mut pinv = Vec::with_capacity(maps.len());
        let mut x_gauss = Vec::with_capacity(maps.len());
        for (k, g) in maps.iter().enumerate() {
            let a = g.columns(0, dim).into_owned();
            let p = a
                .clone()
                .pseudo_inverse(
                    charts.config.pinv_tolerance
                        * a.clone().singular_values().max().max(f64::MIN_POSITIVE),
                )
                .map_err(|e| ReduceError::Numerical(format!("pseudo-inverse of chart {k}: {e}")))?;
            pinv.push(p);
            let lam = DMatrix::from_diagonal(&DVector::from_iterator(
                dim,
                charts.eigenvalues[k].iter().take(dim).copied(),
            ));
            let mut cov = &a * lam * a.transpose();
            let ridge =
                charts.config.ridge.max(1e-12) * (cov.trace() / dim as f64).max(f64::MIN_POSITIVE);
            for i in 0..dim {
                cov[(i, i)] += ridge;
            }
            let chol = cov.cholesky().ok_or_else(|| {
                ReduceError::Numerical(format!("chart {k}: singular embedding covariance"))
            })?;
            let logdet = 2.0 * chol.l().diagonal().iter().map(|v| v.ln()).sum::<f64>();
            x_gauss.push((chol.inverse(), logdet));
        }
        Ok(Chart {
            charts,
            dim,
            maps,
            spectrum,
            pinv,
            x_gauss,
        })
    }

    /// Forward map (2.52): `x̂ = Σ_k p_{k|y} G_k [u_k; 1]`.
    pub fn forward(&self, y: &DVector<f64>) -> Result<DVector<f64>> {
        let p = self.charts.posteriors(y)?;
        let mut x = DVector::zeros(self.dim);
        for (k, &pk) in p.iter().enumerate() {
            if pk < 1e-14 {
                continue;
            }
            let u = self.charts.local_coords(k, self.dim, y);
            let g = &self.maps[k];
            x += (g.columns(0, self.dim) * u + g.column(self.dim)) * pk;
        }
        Ok(x)
    }

    /// Embedding-space posteriors `p_{k|x}(x)` (2.55).
    pub fn x_posteriors(&self, x: &DVector<f64>) -> Result<Vec<f64>> {
        ReduceError::check_size("embedding coordinate count", self.dim, x.len())?;
        if x.iter().any(|v| !v.is_finite()) {
            return Err(ReduceError::NonFinite("embedding coordinates"));
        }
        let logs: Vec<f64> = (0..self.maps.len())
            .map(|k| {
                let diff = x - self.maps[k].column(self.dim);
                let (inv, logdet) = &self.x_gauss[k];
                -0.5 * (diff.dot(&(inv * &diff)) + logdet)
            })
            .collect();
        Ok(softmax(&logs))
    }

    /// Posterior-mean back-projection (2.54).
    pub fn backward(&self, x: &DVector<f64>) -> Result<DVector<f64>> {
        let p = self.x_posteriors(x)?;
        let mut y = DVector::zeros(self.charts.ambient_dim());
        for (k, &pk) in p.iter().enumerate() {
            if pk < 1e-14 {
                continue;
            }
            let local = &self.pinv[k] * (x - self.maps[k].column(self.dim));
            let yk = self.charts.centres.row(k).transpose()
                + self.charts.eigenvectors[k].columns(0, self.dim) * local;
            y += yk * pk;
        }
        Ok(y)
    }

    /// Embedding of the chart centres (training points), `N × d`.
    pub fn embedding(&self) -> Result<DMatrix<f64>> {
        let n = self.charts.len();
        let mut e = DMatrix::zeros(n, self.dim);
        for i in 0..n {
            let x = self.forward(&self.charts.centres.row(i).transpose())?;
            e.row_mut(i).copy_from(&x.transpose());
        }
        Ok(e)
    }

    /// Round trip of the training points (chart centres): `ŷ_i = backward(forward(y_i))`.
    pub fn round_trip(&self) -> Result<RoundTrip> {
        let c = &self.charts.centres;
        let mean = c.row_mean();
        let mut squared_residuals = Vec::with_capacity(c.nrows());
        let mut centred_norm2 = 0.0;
        for i in 0..c.nrows() {
            let y = c.row(i).transpose();
            let yh = self.backward(&self.forward(&y)?)?;
            squared_residuals.push((&yh - &y).norm_squared());
            centred_norm2 += (y - mean.transpose()).norm_squared();
        }
        Ok(RoundTrip {
            squared_residuals,
            centred_norm2,
        })
    }

    /// Relative reconstruction error of the training points, `sqrt(Σ ‖ŷ_i − y_i‖² / Σ ‖y_i − ȳ‖²)`
    /// with `ŷ_i = backward(forward(y_i))` (see [`RoundTrip::relative_error`]).
    pub fn reconstruction_error(&self) -> Result<f64> {
        Ok(self.round_trip()?.relative_error())
    }
}

/// Round-trip residuals of a chart's training points (forward map (2.52), then
/// back-projection (2.54)), in the chart's ambient coordinates.
#[derive(Debug, Clone, PartialEq)]
pub struct RoundTrip {
    /// `‖ŷ_i − y_i‖²` for every training point.
    pub squared_residuals: Vec<f64>,
    /// `Σ_i ‖y_i − ȳ‖²`: squared norm of the centred training points.
    pub centred_norm2: f64,
}

impl RoundTrip {
    /// `Σ_i ‖ŷ_i − y_i‖²`.
    pub fn residual_norm2(&self) -> f64 {
        self.squared_residuals.iter().sum()
    }

    /// Norm ratio `sqrt(Σ ‖ŷ_i − y_i‖² / Σ ‖y_i − ȳ‖²)`.
    pub fn relative_error(&self) -> f64 {
        self.unexplained_fraction().sqrt()
    }

    /// Fraction of the centred data's variance left unexplained,
    /// `Σ ‖ŷ_i − y_i‖² / Σ ‖y_i − ȳ‖²` (the square of [`RoundTrip::relative_error`]).
    pub fn unexplained_fraction(&self) -> f64 {
        self.residual_norm2() / self.centred_norm2
    }
}

/// Leave-one-out reconstruction of every point: the chart (and, for comparison, the linear
/// PCA subspace of the same dimension) is built from the other points only, and the held-out
/// point is mapped forward (2.52) and back (2.54) (respectively projected onto the subspace).
#[derive(Debug, Clone, PartialEq)]
pub struct HeldOut {
    /// `‖ŷ_i − y_i‖²` through the chart of the other points.
    pub chart: Vec<f64>,
    /// `‖ỹ_i − y_i‖²` for the projection onto the other points' `d` principal directions.
    pub linear: Vec<f64>,
    /// `‖y_i − m_i‖²`, `m_i` the mean of the other points.
    pub deviation: Vec<f64>,
}

impl HeldOut {
    /// `sqrt(Σ ‖ŷ_i − y_i‖² / Σ ‖y_i − m_i‖²)` for the chart.
    pub fn chart_relative(&self) -> f64 {
        (self.chart.iter().sum::<f64>() / self.deviation.iter().sum::<f64>()).sqrt()
    }

    /// The same ratio for the linear subspace.
    pub fn linear_relative(&self) -> f64 {
        (self.linear.iter().sum::<f64>() / self.deviation.iter().sum::<f64>()).sqrt()
    }

    /// Number of points reconstructed better by the chart than by the linear subspace.
    pub fn chart_better(&self) -> usize {
        self.chart
            .iter()
            .zip(&self.linear)
            .filter(|(c, l)| c < l)
            .count()
    }
}

/// Leave-one-out errors of `d`-dimensional charts (built with `config`; a default σ is
/// recomputed from the remaining points) and of `d`-dimensional PCA, for every row of
/// `points`.
pub fn held_out_errors(points: &DMatrix<f64>, d: usize, config: ChartingConfig) -> Result<HeldOut> {
    use rayon::prelude::*;
    let (n, k) = points.shape();
    if n < d + 4 || d == 0 || d > k {
        return Err(ReduceError::InvalidParameter(format!(
            "leave-one-out with d = {d}, {n} points in {k} dimensions"
        )));
    }
    let per_point: Vec<(f64, f64, f64)> = (0..n)
        .into_par_iter()
        .map(|i| {
            let rest = points.clone().remove_row(i);
            let y = points.row(i).transpose();
            let chart = Charts::fit(&rest, config)?.connect(d)?;
            let yh = chart.backward(&chart.forward(&y)?)?;
            let mean = rest.row_mean().transpose();
            let centred = DMatrix::from_fn(n - 1, k, |r, c| rest[(r, c)] - mean[c]);
            let svd = centred.svd(false, true);
            let vt = svd
                .v_t
                .ok_or_else(|| ReduceError::Numerical("SVD failed".into()))?;
            // Singular values come unsorted from nalgebra: take the d largest.
            let mut order: Vec<usize> = (0..svd.singular_values.len()).collect();
            order.sort_by(|&a, &b| svd.singular_values[b].total_cmp(&svd.singular_values[a]));
            let dev = &y - &mean;
            let mut yl = mean.clone();
            for &c in order.iter().take(d) {
                let v = vt.row(c).transpose();
                yl += &v * v.dot(&dev);
            }
            Ok((
                (yh - &y).norm_squared(),
                (yl - &y).norm_squared(),
                dev.norm_squared(),
            ))
        })
        .collect::<Result<_>>()?;
    Ok(HeldOut {
        chart: per_point.iter().map(|p| p.0).collect(),
        linear: per_point.iter().map(|p| p.1).collect(),
        deviation: per_point.iter().map(|p| p.2).collect(),
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Fraction of the variance of `target` not explained by an affine function of `x`.
    fn affine_residual(x: &DMatrix<f64>, target: &DMatrix<f64>) -> f64 {
        let n = x.nrows();
        let a = DMatrix::from_fn(n, x.ncols() + 1, |i, j| {
            if j < x.ncols() {
                x[(i, j)]
            } else {
                1.0
            }
        });
        let coef = a.clone().svd(true, true).solve(target, 1e-12).unwrap();
        let r = target - &a * coef;
        let mean = target.row_mean();
        let tot: f64 = (0..n).map(|i| (target.row(i) - &mean).norm_squared()).sum();
        r.norm_squared() / tot
    }

    /// Points on a 2-D strip rolled up in 3-D (a Swiss roll with 1.5 turns), on a jittered grid.
    fn roll(nt: usize, nh: usize) -> (DMatrix<f64>, DMatrix<f64>) {
        let n = nt * nh;
        let mut p = DMatrix::zeros(n, 3);
        let mut truth = DMatrix::zeros(n, 2);
        for a in 0..nt {
            for b in 0..nh {
                let i = a * nh + b;
                let t = 1.5
                    * std::f64::consts::PI
                    * (1.0 + 2.0 * (a as f64 + 0.3 * ((b * 7 % 5) as f64 / 5.0)) / nt as f64);
                let h = 10.0 * b as f64 / nh as f64;
                p[(i, 0)] = t * t.cos();
                p[(i, 1)] = h;
                p[(i, 2)] = t * t.sin();
                // Arc length of the spiral r = t: ∫ sqrt(1 + t²) dt.
                let s = 0.5 * (t * (1.0 + t * t).sqrt() + (t + (1.0 + t * t).sqrt()).ln());
                truth[(i, 0)] = s;
                truth[(i, 1)] = h;
            }
        }
        (p, truth)
    }

    #[test]
    fn covariances_solve_the_map_system() {
        let (p, _) = roll(12, 5);
        let ch = Charts::fit(
            &p,
            ChartingConfig {
                eigen_floor: 0.0,
                posterior_broadening: 0.0,
                ..Default::default()
            },
        )
        .unwrap();
        // Re-check the stationarity equation for one chart.
        let n = p.nrows();
        let i = 17;
        let d = euclidean_distances(&p);
        let w = d.map(|v| (-(v * v) / (2.0 * ch.sigma * ch.sigma)).exp());
        let cov = |k: usize| {
            &ch.eigenvectors[k]
                * DMatrix::from_diagonal(&DVector::from_vec(ch.eigenvalues[k].clone()))
                * ch.eigenvectors[k].transpose()
        };
        let a: f64 = w.row(i).sum();
        let b = a - 1.0;
        let mut lhs = cov(i) * (a + b);
        let mut rhs = DMatrix::zeros(3, 3);
        for j in 0..n {
            if j != i {
                lhs -= cov(j) * w[(i, j)];
                let dl = (p.row(j) - p.row(i)).transpose();
                rhs += &dl * dl.transpose() * (2.0 * w[(i, j)]);
            }
        }
        assert!((lhs - &rhs).amax() < 1e-8 * rhs.amax().max(1e-12));
    }

    #[test]
    fn unrolls_a_swiss_roll_and_reconstructs_it() {
        let (p, truth) = roll(60, 8);
        let ch = Charts::fit(&p, ChartingConfig::default()).unwrap();
        let chart = ch.connect(2).unwrap();
        let e = chart.embedding().unwrap();
        // Each embedding axis is normalised separately, so compare up to an affine map: the
        // unrolled (arc length, height) coordinates must be an affine function of the chart.
        let unexplained = affine_residual(&e, &truth);
        assert!(
            unexplained < 0.02,
            "unexplained fraction of the unrolled strip: {unexplained}"
        );
        // The 2-D chart reproduces the 3-D points far better than the best 2-D linear subspace.
        let err2 = chart.reconstruction_error().unwrap();
        let pca_err = {
            let mean = p.row_mean();
            let c = DMatrix::from_fn(p.nrows(), 3, |i, j| p[(i, j)] - mean[j]);
            let sv = c.singular_values();
            let mut s: Vec<f64> = sv.iter().map(|v| v * v).collect();
            s.sort_by(|a, b| b.total_cmp(a));
            (s[2] / s.iter().sum::<f64>()).sqrt()
        };
        assert!(err2 < 0.5 * pca_err, "chart {err2} vs linear {pca_err}");
    }

    /// Distance from `y` to the Swiss-roll surface of [`roll`] (dense search over its
    /// parameters, then the exact height).
    fn distance_to_roll(y: &DVector<f64>) -> f64 {
        let h = y[1].clamp(0.0, 10.0);
        let mut best = f64::INFINITY;
        for s in 0..=6000 {
            let t = 1.5 * std::f64::consts::PI * (1.0 + 2.0 * s as f64 / 6000.0);
            let d2 = (t * t.cos() - y[0]).powi(2) + (t * t.sin() - y[2]).powi(2);
            best = best.min(d2);
        }
        (best + (y[1] - h).powi(2)).sqrt()
    }

    #[test]
    fn long_moves_in_the_chart_stay_on_the_roll_where_straight_lines_leave_it() {
        let (p, _) = roll(60, 8);
        let chart = Charts::fit(&p, ChartingConfig::default())
            .unwrap()
            .connect(2)
            .unwrap();
        // From a point on the inner turn to one on the next turn, same height: the straight
        // line crosses the empty space between the turns.
        let (a, b) = (4 * 8 + 3, 44 * 8 + 3);
        let (ya, yb) = (p.row(a).transpose(), p.row(b).transpose());
        let (ea, eb) = (chart.forward(&ya).unwrap(), chart.forward(&yb).unwrap());
        let (mut worst_chart, mut worst_line) = (0.0f64, 0.0f64);
        for s in 0..=20 {
            let t = s as f64 / 20.0;
            let yc = chart.backward(&(&ea + (&eb - &ea) * t)).unwrap();
            let yl = &ya + (&yb - &ya) * t;
            worst_chart = worst_chart.max(distance_to_roll(&yc));
            worst_line = worst_line.max(distance_to_roll(&yl));
        }
        // Spacing of the turns is 2π ≈ 6.3; the chord leaves the surface by several units.
        assert!(worst_line > 2.0, "straight line: {worst_line}");
        assert!(
            worst_chart < 0.15 * worst_line,
            "chart path {worst_chart} vs straight line {worst_line}"
        );
    }

    #[test]
    fn held_out_error_drops_at_the_true_dimension() {
        // A 2-D sheet bent in 4-D (not a linear subspace), sampled on a jittered grid.
        let g = 10;
        let n = g * g;
        let p = DMatrix::from_fn(n, 4, |i, c| {
            let u = (i / g) as f64 / (g - 1) as f64 * 3.0 + 0.05 * ((i * 7 % 5) as f64);
            let v = (i % g) as f64 / (g - 1) as f64 * 3.0 + 0.05 * ((i * 3 % 4) as f64);
            match c {
                0 => u,
                1 => v,
                2 => 0.6 * (u * u - v),
                _ => 0.5 * (u * v).sin(),
            }
        });
        let cfg = ChartingConfig::default();
        let charts = Charts::fit(&p, cfg).unwrap();
        let train: Vec<f64> = (1..=3)
            .map(|d| charts.connect(d).unwrap().reconstruction_error().unwrap())
            .collect();
        let median = |v: &[f64]| {
            let mut v: Vec<f64> = v.iter().map(|x| x.sqrt()).collect();
            v.sort_by(f64::total_cmp);
            v[v.len() / 2]
        };
        let h1 = held_out_errors(&p, 1, cfg).unwrap();
        let h2 = held_out_errors(&p, 2, cfg).unwrap();
        eprintln!(
            "train {train:?}; held-out medians chart d=1 {} d=2 {}, plane d=2 {}, chart better {}",
            median(&h1.chart),
            median(&h2.chart),
            median(&h2.linear),
            h2.chart_better()
        );
        // Training points: one dimension cannot describe the sheet, two do.
        assert!(train[1] < 0.3 * train[0], "{train:?}");
        // Held-out points (typical error): the 2-D chart generalises, and beats the plane.
        assert!(median(&h2.chart) < 0.3 * median(&h1.chart));
        assert!(median(&h2.chart) < 0.5 * median(&h2.linear));
        assert!(h2.chart_better() > n / 2, "{} of {n}", h2.chart_better());
        assert!(held_out_errors(&p, 0, cfg).is_err());
    }

    #[test]
    fn posteriors_are_distributions_and_bad_input_is_rejected() {
        let (p, _) = roll(10, 4);
        let ch = Charts::fit(&p, ChartingConfig::default()).unwrap();
        let post = ch.posteriors(&p.row(3).transpose()).unwrap();
        assert!((post.iter().sum::<f64>() - 1.0).abs() < 1e-12);
        assert!(post.iter().all(|&v| v >= 0.0));
        assert!(ch.posteriors(&DVector::zeros(2)).is_err());
        assert!(ch.connect(0).is_err());
        let mut bad = p.clone();
        bad[(0, 0)] = f64::NAN;
        assert!(Charts::fit(&bad, ChartingConfig::default()).is_err());
    }
}
