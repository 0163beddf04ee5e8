//! Levenberg-Marquardt with bounds by reparameterisation and a deterministic multi-start.

use crate::data::{FitData, Rows, Subset};
use crate::error::Result;
use crate::model::{ModelKind, Parametric};
use crate::objective::{normal_equations, relative_error, Objective};
use levenberg_marquardt::{LeastSquaresProblem, LevenbergMarquardt};
use nalgebra::{DMatrix, DVector, Dyn, Owned};
use rand::{Rng, SeedableRng};

/// Options of a fit.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FitOptions {
    /// What to minimise.
    pub objective: Objective,
    /// Which bins to fit on (log and Ngan objectives).
    pub subset: Subset,
    /// Number of starts (the first is the default start).
    pub starts: usize,
    /// Seed of the multi-start.
    pub seed: u64,
    /// Solver patience: at most `patience · (dim + 1)` evaluations per start.
    pub patience: usize,
}

impl Default for FitOptions {
    fn default() -> Self {
        FitOptions {
            objective: Objective::Log,
            subset: Subset::All,
            starts: 4,
            seed: 1,
            patience: 40,
        }
    }
}

/// The outcome of one start.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct StartOutcome {
    /// Relative error (objective metric on the fit rows) at the end of this start.
    pub error: f64,
    /// Whether the solver reported convergence.
    pub converged: bool,
    /// Residual evaluations spent.
    pub evaluations: usize,
    /// The solver's termination reason.
    pub termination: String,
}

/// A fitted model.
#[derive(Debug, Clone, PartialEq)]
pub struct FitResult {
    /// The model with its fitted parameters.
    pub model: Parametric,
    /// The objective minimised.
    pub objective: Objective,
    /// Relative error in the objective's metric on the fit rows.
    pub fit_error: f64,
    /// Whether the best start converged. When `false`, [`FitResult::model`] is the best point
    /// the solver reached.
    pub converged: bool,
    /// Index of the best start (0 = the default start).
    pub best_start: usize,
    /// Every start, in order.
    pub starts: Vec<StartOutcome>,
    /// Rows fitted.
    pub rows: usize,
}

impl FitResult {
    /// The material spec of the fitted model.
    pub fn spec(&self) -> String {
        self.model.spec()
    }
}

struct Compressed<'a> {
    kind: ModelKind,
    rows: &'a Rows,
    p: DVector<f64>,
    r: Option<DVector<f64>>,
    j: Option<DMatrix<f64>>,
    evaluations: usize,
}

impl Compressed<'_> {
    fn update(&mut self) {
        self.evaluations += 1;
        let dim = self.p.len();
        let ne = normal_equations(self.kind, self.rows, self.p.as_slice());
        let ok = ne.rtr.is_finite() && ne.jtr.iter().chain(&ne.jtj).all(|v| v.is_finite());
        if !ok {
            self.reject(dim);
            return;
        }
        let mut a = DMatrix::from_row_slice(dim, dim, &ne.jtj);
        let scale = (0..dim).map(|i| a[(i, i)]).fold(0.0f64, f64::max);
        for i in 0..dim {
            a[(i, i)] += 1e-12 * scale + 1e-300;
        }
        let Some(ch) = a.cholesky() else {
            self.reject(dim);
            return;
        };
        let l = ch.l();
        let jtr = DVector::from_column_slice(&ne.jtr);
        let rp = l
            .solve_lower_triangular(&jtr)
            .unwrap_or_else(|| DVector::zeros(dim));
        let extra = (ne.rtr - rp.norm_squared()).max(0.0).sqrt();
        let mut r = DVector::zeros(dim + 1);
        r.rows_mut(0, dim).copy_from(&rp);
        r[dim] = extra;
        let mut j = DMatrix::zeros(dim + 1, dim);
        j.view_mut((0, 0), (dim, dim)).copy_from(&l.transpose());
        self.r = Some(r);
        self.j = Some(j);
    }
}

impl Compressed<'_> {
    /// A point where the model cannot be evaluated: a huge residual makes the solver reject
    /// the step and shrink its trust region (returning no residual would end the fit).
    fn reject(&mut self, dim: usize) {
        let mut r = DVector::zeros(dim + 1);
        r[dim] = 1e100;
        self.r = Some(r);
        if self.j.is_none() {
            self.j = Some(DMatrix::zeros(dim + 1, dim));
        }
    }
}

impl LeastSquaresProblem<f64, Dyn, Dyn> for Compressed<'_> {
    type ResidualStorage = Owned<f64, Dyn>;
    type JacobianStorage = Owned<f64, Dyn, Dyn>;
    type ParameterStorage = Owned<f64, Dyn>;

    fn set_params(&mut self, x: &DVector<f64>) {
        self.p.copy_from(x);
        self.update();
    }
    fn params(&self) -> DVector<f64> {
        self.p.clone()
    }
    fn residuals(&self) -> Option<DVector<f64>> {
        self.r.clone()
    }
    fn jacobian(&self) -> Option<DMatrix<f64>> {
        self.j.clone()
    }
}

/// Solver vectors of the starts: the default first, then shape parameters drawn uniformly (in
/// solver space) over each parameter's typical range with a generator seeded by `seed`.
pub fn starts(kind: ModelKind, data: &FitData, count: usize, seed: u64) -> Vec<Vec<f64>> {
    let p0 = kind.to_solver(&kind.default_start(data.diffuse_estimate()));
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed ^ (kind as u64).wrapping_mul(0x9e37));
    let mut out = vec![p0.clone()];
    for _ in 1..count.max(1) {
        let mut p = p0.clone();
        let mut k = 0;
        for d in kind.params() {
            let (a, b) = (d.bound.to_solver(d.range.0), d.bound.to_solver(d.range.1));
            if d.colour {
                // Albedos keep their start; per-channel shape parameters are drawn per channel.
                if (b - a).abs() > 0.0 {
                    for c in 0..3 {
                        p[k + c] = rng.gen_range(a.min(b)..=a.max(b));
                    }
                }
                k += 3;
                continue;
            }
            let (a, b) = (d.bound.to_solver(d.range.0), d.bound.to_solver(d.range.1));
            p[k] = if (b - a).abs() > 0.0 {
                rng.gen_range(a.min(b)..=a.max(b))
            } else {
                a
            };
            k += 1;
        }
        out.push(p);
    }
    out
}

/// Runs the solver from solver vector `p0` on `rows`.
pub fn solve_from(
    kind: ModelKind,
    rows: &Rows,
    p0: &[f64],
    patience: usize,
) -> (Vec<f64>, StartOutcome) {
    let mut problem = Compressed {
        kind,
        rows,
        p: DVector::from_column_slice(p0),
        r: None,
        j: None,
        evaluations: 0,
    };
    problem.update();
    let (problem, report) = LevenbergMarquardt::new()
        .with_patience(patience.max(1))
        .minimize(problem);
    let mut p: Vec<f64> = problem.p.iter().copied().collect();
    let mut err = relative_error(kind, rows, &kind.to_model(&p));
    let start_err = relative_error(kind, rows, &kind.to_model(p0));
    // The solver keeps its best point; guard against a final state worse than the start (a
    // failed evaluation stops it where it stood).
    if !err.is_finite() || err > start_err {
        p = p0.to_vec();
        err = start_err;
    }
    let outcome = StartOutcome {
        error: err,
        converged: report.termination.was_successful(),
        evaluations: problem.evaluations,
        termination: format!("{:?}", report.termination),
    };
    (p, outcome)
}

/// Fits `kind` to `data` with `options`: every start is run and the lowest error wins.
///
/// The solver is Levenberg-Marquardt with bounds by reparameterisation and a deterministic
/// multi-start.
/// The residual vector of a fit on every valid bin has millions of entries; the
/// `levenberg-marquardt` crate would store its Jacobian densely. Instead each evaluation
/// accumulates the normal equations (JᵀJ, Jᵀr, rᵀr) in parallel and hands the solver an
/// equivalent square problem: with JᵀJ = L Lᵀ, the residuals r' = (L⁻¹ Jᵀr, √(rᵀr − |L⁻¹Jᵀr|²))
/// and Jacobian J' = (Lᵀ; 0) give the same ‖r‖², the same J'ᵀJ' and the same J'ᵀr', so every
/// step, trust-region update and convergence test of the solver is the one on the full problem.
///
/// # Examples
///
/// ```
/// use fit::{fit, FitData, FitOptions, ModelKind, Objective, Subset};
/// // Fitting a Lambertian model to a Lambertian table recovers its albedo.
/// let data = FitData::new(&brdf::load("lambert:kd=0.3/0.5/0.7").unwrap().tabulate()).unwrap();
/// let opts = FitOptions {
///     objective: Objective::Ngan,
///     subset: Subset::Random { bins: 1000, seed: 1 },
///     starts: 2,
///     ..FitOptions::default()
/// };
/// let r = fit(ModelKind::Lambert, &data, &opts).unwrap();
/// assert_eq!(r.starts.len(), 2);
/// assert!(r.fit_error < 1e-3, "{}", r.fit_error);
/// for (got, want) in r.model.q.iter().zip([0.3, 0.5, 0.7]) {
///     assert!((got - want).abs() < 1e-3, "{got} vs {want}");
/// }
/// ```
pub fn fit(kind: ModelKind, data: &FitData, options: &FitOptions) -> Result<FitResult> {
    let rows = options.objective.rows(data, options.subset)?;
    Ok(fit_rows(kind, data, &rows, options))
}

/// [`fit`] on rows built beforehand (the study reuses them for every model).
pub fn fit_rows(kind: ModelKind, data: &FitData, rows: &Rows, options: &FitOptions) -> FitResult {
    let mut best: (Vec<f64>, usize, f64) = (Vec::new(), 0, f64::INFINITY);
    let mut outcomes = Vec::new();
    for (s, p0) in starts(kind, data, options.starts, options.seed)
        .into_iter()
        .enumerate()
    {
        let (p, o) = solve_from(kind, rows, &p0, options.patience);
        tracing::debug!(
            model = kind.name(),
            start = s,
            error = o.error,
            "start done"
        );
        if s == 0 || o.error < best.2 {
            best = (p, s, o.error);
        }
        outcomes.push(o);
    }
    let (p, b, _) = best;
    let o = &outcomes[b];
    FitResult {
        model: Parametric {
            kind,
            q: kind.to_model(&p),
        },
        objective: options.objective,
        fit_error: o.error,
        converged: o.converged,
        best_start: b,
        starts: outcomes.clone(),
        rows: rows.len(),
    }
}
