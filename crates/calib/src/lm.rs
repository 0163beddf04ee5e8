//! Levenberg–Marquardt on a residual closure, through the `levenberg-marquardt` crate with a
//! central-difference Jacobian.

use crate::error::{CalibError, CalibResult};
use levenberg_marquardt::{LeastSquaresProblem, LevenbergMarquardt, TerminationReason};
use nalgebra::{DMatrix, DVector, Dyn, Owned};

/// Outcome of a least-squares fit.
#[derive(Debug, Clone)]
pub(crate) struct Fit {
    /// Parameters at the minimum.
    pub params: DVector<f64>,
    /// Residuals at the minimum.
    pub residuals: DVector<f64>,
}

impl Fit {
    /// Root mean square of the residuals.
    pub fn rms(&self) -> f64 {
        if self.residuals.is_empty() {
            0.0
        } else {
            (self.residuals.norm_squared() / self.residuals.len() as f64).sqrt()
        }
    }
}

struct ClosureProblem<'a, F: Fn(&DVector<f64>) -> Option<DVector<f64>>> {
    params: DVector<f64>,
    residual: &'a F,
    steps: &'a [f64],
}

impl<F: Fn(&DVector<f64>) -> Option<DVector<f64>>> LeastSquaresProblem<f64, Dyn, Dyn>
    for ClosureProblem<'_, F>
{
    type ResidualStorage = Owned<f64, Dyn>;
    type JacobianStorage = Owned<f64, Dyn, Dyn>;
    type ParameterStorage = Owned<f64, Dyn>;

    fn set_params(&mut self, x: &DVector<f64>) {
        self.params.copy_from(x);
    }

    fn params(&self) -> DVector<f64> {
        self.params.clone()
    }

    fn residuals(&self) -> Option<DVector<f64>> {
        let r = (self.residual)(&self.params)?;
        r.iter().all(|v| v.is_finite()).then_some(r)
    }

    fn jacobian(&self) -> Option<DMatrix<f64>> {
        let n = self.params.len();
        let mut cols: Vec<DVector<f64>> = Vec::with_capacity(n);
        let mut x = self.params.clone();
        for j in 0..n {
            let h = self.steps[j];
            let x0 = x[j];
            x[j] = x0 + h;
            let rp = (self.residual)(&x)?;
            x[j] = x0 - h;
            let rm = (self.residual)(&x)?;
            x[j] = x0;
            if rp.len() != rm.len() {
                return None;
            }
            cols.push((rp - rm) / (2.0 * h));
        }
        let m = cols.first().map_or(0, |c| c.len());
        let jac = DMatrix::from_fn(m, n, |i, j| cols[j][i]);
        jac.iter().all(|v| v.is_finite()).then_some(jac)
    }
}

/// Minimises ‖residual(p)‖² from `start`. `steps[j]` is the finite-difference step of
/// parameter j. Fails with [`CalibError::NotConverged`] on numerical breakdown.
pub(crate) fn minimise<F>(
    what: &str,
    start: DVector<f64>,
    steps: &[f64],
    residual: F,
) -> CalibResult<Fit>
where
    F: Fn(&DVector<f64>) -> Option<DVector<f64>>,
{
    debug_assert_eq!(start.len(), steps.len());
    let problem = ClosureProblem {
        params: start,
        residual: &residual,
        steps,
    };
    let (problem, report) = LevenbergMarquardt::new()
        .with_patience(200)
        .minimize(problem);
    let ok = report.termination.was_successful()
        || matches!(
            report.termination,
            TerminationReason::LostPatience | TerminationReason::NoImprovementPossible(_)
        );
    if !ok {
        return Err(CalibError::NotConverged(format!(
            "{what}: {:?}",
            report.termination
        )));
    }
    tracing::debug!(
        what,
        evaluations = report.number_of_evaluations,
        objective = report.objective_function,
        termination = ?report.termination,
        "least-squares fit"
    );
    let params = problem.params;
    let residuals = residual(&params)
        .filter(|r| r.iter().all(|v| v.is_finite()))
        .ok_or_else(|| CalibError::NotConverged(format!("{what}: non-finite residuals")))?;
    Ok(Fit { params, residuals })
}
