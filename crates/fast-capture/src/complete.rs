//! Completing a partly measured table from the model: measured entries kept, the others
//! predicted, each with its uncertainty.

use crate::error::{FastError, Result};
use crate::plan::residual_log_var;
use brdf::MerlTable;
use rayon::prelude::*;
use reduce::to_log;

/// A table completed from the model.
#[derive(Debug, Clone)]
pub struct Completion {
    /// Every entry: the measured value where there is one, the model's elsewhere.
    pub table: MerlTable,
    /// Per entry (`channel · BINS + bin`): whether it was measured.
    pub measured: Vec<bool>,
    /// Per entry: the standard deviation of a completed entry's log value (`ln(f + ε)`), from
    /// the uncertainty of the coordinates and the model's residual; 0 for measured entries.
    pub log_sd: Vec<f32>,
    /// The material's coordinates on the model's first components.
    pub coordinates: Vec<f64>,
    /// Variance per log entry of the model's residual (the fit's noise term).
    pub residual_log_var: f64,
    /// Entries measured.
    pub measured_entries: usize,
}

/// Completes `measured` (missing entries negative, as a capture writes them) from the first `k`
/// components of `model`.
///
/// The coordinates are the posterior mean of the Bayesian reading of the model that the plan
/// uses ([`crate::plan()`]): least squares of the log values over the measured entries with the
/// ridge `σ² Σ x_k² N / λ_k` ([`reduce::Pca::project_masked_posterior`]), σ² the model's
/// residual variance per entry after `k` components. Measured entries keep their measured
/// value; the others get the model's (`exp` of the log prediction, less the log floor, at
/// least 0) and the standard deviation `σ √(1 + uᵀ H⁻¹ u)` of their log value.
pub fn complete(model: &reduce::Model, measured: &MerlTable, k: usize) -> Result<Completion> {
    let pca = &model.pca;
    if pca.dim != brdf::MATERIAL_DIM {
        return Err(FastError::ModelShape {
            dim: pca.dim,
            expected: brdf::MATERIAL_DIM,
        });
    }
    let k = k.min(pca.components);
    if k == 0 {
        return Err(FastError::InvalidOption(
            "the model has no component".into(),
        ));
    }
    let values = measured.values();
    let known: Vec<bool> = values.iter().map(|v| v.is_finite() && *v >= 0.0).collect();
    let measured_entries = known.iter().filter(|&&m| m).count();
    if measured_entries == 0 {
        return Err(FastError::InvalidOption(
            "the capture measured no entry of the table".into(),
        ));
    }
    let y: Vec<f32> = values
        .iter()
        .zip(&known)
        .map(|(&v, &m)| if m { to_log(v) } else { 0.0 })
        .collect();
    let sigma2 = residual_log_var(pca, k);
    let (x, h) = pca.project_masked_posterior(&y, &known, k, sigma2)?;
    let predicted = model.synthesize(&x)?;
    let chol = h.cholesky().ok_or_else(|| {
        FastError::InvalidOption("the measured entries do not determine the coordinates".into())
    })?;
    // H⁻¹ = L⁻ᵀ L⁻¹: the variance of uᵀx is σ² ‖L⁻¹ u‖².
    let l_inv = chol
        .l()
        .try_inverse()
        .ok_or_else(|| FastError::InvalidOption("singular normal equations".into()))?;
    let kk = pca.components;
    let log_sd: Vec<f32> = (0..values.len())
        .into_par_iter()
        .map(|d| {
            if known[d] {
                return 0.0;
            }
            let u = &pca.basis[d * kk..d * kk + k];
            let mut q = 0.0;
            for r in 0..k {
                let mut z = 0.0;
                for c in 0..=r {
                    z += l_inv[(r, c)] * u[c] as f64;
                }
                q += z * z;
            }
            (sigma2 * (1.0 + q)).sqrt() as f32
        })
        .collect();
    let out: Vec<f64> = values
        .iter()
        .zip(&predicted)
        .zip(&known)
        .map(|((&v, &p), &m)| if m { v } else { p })
        .collect();
    let name = format!("{} (completed, PCA {k})", brdf::Brdf::name(measured));
    Ok(Completion {
        table: MerlTable::from_values(out)?.with_name(name),
        measured: known,
        log_sd,
        coordinates: x,
        residual_log_var: sigma2,
        measured_entries,
    })
}
