//! Choosing the lamp positions: a greedy Bayesian A-optimal design on the model's components,
//! within a capture-clock budget.

use crate::coverage::Coverage;
use crate::error::{FastError, Result};
use nalgebra::DMatrix;
use rayon::prelude::*;
use serde::{Deserialize, Serialize};

/// Version of the `plan.json` layout.
pub const PLAN_VERSION: u32 = 1;

/// The rig's timing, for the predicted clock: each position is a move (travel at the turntable's
/// speed, then settling) and its exposures, each followed by a sensor readout.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct ClockModel {
    /// Sensor readout and transfer time per frame, seconds.
    pub readout_s: f64,
    /// Turntable speed, degrees per second.
    pub speed_deg_per_s: f64,
    /// Settling time after each move, seconds.
    pub settle_s: f64,
}

impl Default for ClockModel {
    /// The simulated rig's timing (`hal_sim::TimingConfig::default()`, the thesis's gantry).
    fn default() -> Self {
        let t = hal_sim::TimingConfig::default();
        Self {
            readout_s: t.readout_s,
            speed_deg_per_s: t.turntable_speed_deg_per_s,
            settle_s: t.settle_s,
        }
    }
}

impl ClockModel {
    /// Clock of a capture at `angles_deg` (visited in increasing order from 0°) taking at most
    /// the exposures `ladder` at each: moves, settling, exposures and readouts. With adaptive
    /// bracketing a position takes a subset of the ladder, so this is an upper bound.
    pub fn capture_s(&self, angles_deg: &[f64], ladder: &[f64]) -> f64 {
        let mut sorted = angles_deg.to_vec();
        sorted.sort_by(f64::total_cmp);
        let mut at = 0.0;
        let mut travel = 0.0;
        for &a in &sorted {
            travel += (a - at).abs();
            at = a;
        }
        let per_position =
            self.settle_s + ladder.iter().sum::<f64>() + ladder.len() as f64 * self.readout_s;
        travel / self.speed_deg_per_s + sorted.len() as f64 * per_position
    }
}

/// How the planner weighs the entries a full capture reaches.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum Weighting {
    /// Every entry's log error counts alike (the median |log| error).
    Uniform,
    /// An entry's log error counts by `(f̄ cos θi)²`, `f̄` the model's mean material: its share
    /// of the cosine-weighted error ([`brdf::metrics::cosine_weighted_relative_rms`]), which the
    /// highlight dominates. The default: on the four development materials of the study it
    /// lowered the larger of the two error ratios to the model's floor from 0.62 to 0.53 on
    /// average (aluminium's cosine-weighted ratio from 1.73 to 1.36).
    #[default]
    Cosine,
}

/// What the planner may spend and how it scores positions.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct PlanOptions {
    /// Most lamp positions.
    pub max_positions: usize,
    /// Capture-clock budget, seconds: no position is added that would take the predicted clock
    /// past it.
    pub budget_s: f64,
    /// Longest exposure, seconds (`None`: the thesis's ladder up to 20 s).
    pub max_exposure_s: Option<f64>,
    /// Components of the model the plan and the completion use (at most the model's).
    pub components: usize,
    /// Candidate lamp positions, evenly spaced over the capture's half circle
    /// ([`gantry_hal::position_angles`]).
    pub candidates: usize,
    /// The rig's timing.
    pub clock: ClockModel,
    /// How the entries a full capture reaches are weighed (plans stored before this option
    /// existed weighed them alike).
    #[serde(default = "uniform")]
    pub weighting: Weighting,
}

fn uniform() -> Weighting {
    Weighting::Uniform
}

impl Default for PlanOptions {
    fn default() -> Self {
        Self {
            max_positions: 40,
            budget_s: 600.0,
            max_exposure_s: Some(DEFAULT_MAX_EXPOSURE_S),
            components: 45,
            candidates: gantry_hal::THESIS_POSITIONS,
            clock: ClockModel::default(),
            weighting: Weighting::default(),
        }
    }
}

/// Default longest exposure of a fast capture, seconds: the thesis ladder's step at about 2 s
/// (its 20 s and 9.3 s frames alone take longer than a whole fast position).
pub const DEFAULT_MAX_EXPOSURE_S: f64 = 2.0;

impl PlanOptions {
    /// Checks the options.
    pub fn validate(&self) -> Result<()> {
        let bad = |s: String| Err(FastError::InvalidOption(s));
        if self.max_positions == 0 {
            return bad("at least one lamp position is needed".into());
        }
        if !(self.budget_s.is_finite() && self.budget_s > 0.0) {
            return bad(format!("clock budget {} s must be positive", self.budget_s));
        }
        if self.components == 0 {
            return bad("at least one component is needed".into());
        }
        if self.candidates < self.max_positions.min(2) {
            return bad(format!("{} candidate positions", self.candidates));
        }
        let c = self.clock;
        let finite = [c.readout_s, c.settle_s, c.speed_deg_per_s]
            .iter()
            .all(|v| v.is_finite());
        if !(finite && c.readout_s >= 0.0 && c.settle_s >= 0.0 && c.speed_deg_per_s > 0.0) {
            return bad(format!("clock model {c:?}"));
        }
        if let Some(cap) = self.max_exposure_s {
            let shortest = hdr::thesis_ladder()[0];
            if !(cap.is_finite() && cap >= shortest) {
                return bad(format!(
                    "longest exposure {cap} s is below the ladder's shortest, {shortest} s"
                ));
            }
        }
        Ok(())
    }

    /// The exposures every position may take.
    pub fn ladder(&self) -> Vec<f64> {
        let mut spec = acquire::JobSpec::new("", 1);
        spec.max_exposure_s = self.max_exposure_s;
        spec.ladder()
    }
}

/// One position the planner added, in the order it chose them.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct PlanStep {
    /// Lamp angle, degrees.
    pub angle_deg: f64,
    /// Entries (channel, bin) this position reaches.
    pub entries: usize,
    /// Entries it reaches that no earlier choice reached.
    pub new_entries: usize,
    /// Share of the entries a full capture reaches that the positions so far reach.
    pub covered_fraction: f64,
    /// Predicted standard deviation of the completed log values over the entries a full
    /// capture reaches, from the uncertainty of the model's coordinates alone (the model's own
    /// residual comes on top).
    pub predicted_log_sd: f64,
    /// Predicted capture clock with the positions so far, seconds.
    pub clock_s: f64,
}

/// The lamp positions and exposures of a fast capture (`DIR/plan.json`).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct CapturePlan {
    /// Layout version ([`PLAN_VERSION`]).
    pub version: u32,
    /// The positions in capture order (increasing angle), degrees.
    pub angles_deg: Vec<f64>,
    /// The positions in the order the planner chose them, with why.
    pub steps: Vec<PlanStep>,
    /// Exposures a position may take, seconds.
    pub exposures_s: Vec<f64>,
    /// Predicted capture clock, seconds.
    pub predicted_clock_s: f64,
    /// Entries a full capture over every candidate reaches.
    pub full_entries: usize,
    /// Entries the planned positions reach.
    pub covered_entries: usize,
    /// Variance of the model's residual per log entry (the completion's noise term).
    pub residual_log_var: f64,
    /// Ratio of the largest to the smallest eigenvalue of the planned positions' normal
    /// equations (the conditioning criterion of thesis §6.5), prior included.
    pub condition: f64,
    /// Number of materials the model was built from (checked against the model on resume).
    pub model_materials: usize,
    /// The options it was made with.
    pub options: PlanOptions,
}

/// Σ over `entries` of `u uᵀ` for the first `k` of the model's `kk` components (`basis` is
/// dimension-major), accumulated in blocks summed in a fixed order (the same bits on every run,
/// so that a resumed job's plan is the stored one).
fn gram(
    basis: &[f32],
    kk: usize,
    k: usize,
    entries: &[u32],
    weights: Option<&[f64]>,
) -> DMatrix<f64> {
    const BLOCK: usize = 2048;
    let blocks: Vec<DMatrix<f64>> = entries
        .par_chunks(BLOCK)
        .map(|chunk| {
            let a = DMatrix::<f64>::from_fn(chunk.len(), k, |r, c| {
                basis[chunk[r] as usize * kk + c] as f64
            });
            match weights {
                None => a.tr_mul(&a),
                Some(w) => {
                    let wa = DMatrix::<f64>::from_fn(chunk.len(), k, |r, c| {
                        w[chunk[r] as usize] * a[(r, c)]
                    });
                    a.tr_mul(&wa)
                }
            }
        })
        .collect();
    blocks
        .into_iter()
        .fold(DMatrix::zeros(k, k), |sum, block| sum + block)
}

/// Per entry: `(f̄ cos θi)²` of the model's mean material (decoded by its mapping), scaled to
/// average 1 over `entries`.
fn cosine_weights(model: &reduce::Model, entries: &[u32]) -> Result<Vec<f64>> {
    let cw = brdf::metrics::cosine_bin_weights();
    let mut w: Vec<f64> = model
        .mapping
        .to_values(&model.pca.mean)?
        .into_iter()
        .enumerate()
        .map(|(d, f)| (f * cw[d % brdf::BINS] as f64).powi(2))
        .collect();
    let mean = entries.iter().map(|&e| w[e as usize]).sum::<f64>() / entries.len().max(1) as f64;
    if mean > 0.0 {
        w.iter_mut().for_each(|v| *v /= mean);
    }
    Ok(w)
}

/// Variance per entry of the model's corpus left after `k` components.
pub fn residual_log_var(pca: &reduce::Pca, k: usize) -> f64 {
    let n = pca.coords.nrows().max(1) as f64;
    let rest: f64 = pca.eigenvalues.iter().skip(k).sum();
    (rest / (n * pca.dim as f64)).max(1e-8)
}

/// trace(W H⁻¹), or `None` when H is not positive definite.
fn a_criterion(w: &DMatrix<f64>, h: DMatrix<f64>) -> Option<f64> {
    let chol = h.cholesky()?;
    Some(chol.solve(w).trace())
}

/// Chooses lamp positions among `coverage`'s candidates for the first `options.components`
/// components of `model`.
///
/// Read the model as a Bayesian one: a material's table in the model's space (log values for
/// the thesis's model, see [`reduce::Mapping`]) is `mean + U x + e`, the prior of
/// each coordinate `x_k ~ N(0, λ_k / N)` (the corpus's spread along it), and `e` independent
/// per entry with the variance the corpus leaves after `k` components (σ²). Measuring a set of
/// entries S gives the posterior covariance `σ² H⁻¹` with `H = Σ_S u uᵀ + σ² diag(N / λ_k)`;
/// the expected squared error of the completed values over the entries F a full capture reaches
/// is then `σ² trace(W_F H⁻¹)` plus the residual, `W_F = Σ_F u uᵀ`. The planner adds, one at a
/// time, the candidate that lowers `trace(W_F H⁻¹)` most (a greedy A-optimal design, counting
/// an entry again for every position that reaches it), until `max_positions` or until no
/// candidate fits the clock budget. Thesis §6.5 chooses sample points for the
/// linear-combination model by the conditioning of the same normal equations; the plan
/// reports that ratio too.
pub fn plan(
    model: &reduce::Model,
    coverage: &Coverage,
    options: &PlanOptions,
) -> Result<CapturePlan> {
    options.validate()?;
    let pca = &model.pca;
    if pca.dim != brdf::MATERIAL_DIM {
        return Err(FastError::ModelShape {
            dim: pca.dim,
            expected: brdf::MATERIAL_DIM,
        });
    }
    let k = options.components.min(pca.components);
    if k == 0 {
        return Err(FastError::InvalidOption(
            "the model has no component".into(),
        ));
    }
    let kk = pca.components;
    let n = pca.coords.nrows().max(1) as f64;
    let sigma2 = residual_log_var(pca, k);
    let ladder = options.ladder();
    let full = coverage.union();
    let full_list: Vec<u32> = (0..full.len() as u32)
        .filter(|&e| full[e as usize])
        .collect();
    let weights = match options.weighting {
        Weighting::Uniform => None,
        Weighting::Cosine => Some(cosine_weights(model, &full_list)?),
    };
    let w = gram(&pca.basis, kk, k, &full_list, weights.as_deref());
    let per_candidate: Vec<DMatrix<f64>> = coverage
        .entries
        .iter()
        .map(|e| gram(&pca.basis, kk, k, e, None))
        .collect();
    let mut h = DMatrix::<f64>::zeros(k, k);
    for a in 0..k {
        let var = (pca.eigenvalues.get(a).copied().unwrap_or(0.0) / n).max(1e-12);
        h[(a, a)] = sigma2 / var;
    }
    let mut chosen: Vec<usize> = Vec::new();
    let mut reached = vec![false; brdf::MATERIAL_DIM];
    let mut covered = 0usize;
    let mut steps = Vec::new();
    let full_count = full_list.len().max(1);
    while chosen.len() < options.max_positions {
        let best = (0..coverage.angles_deg.len())
            .into_par_iter()
            .filter(|c| !chosen.contains(c))
            .filter_map(|c| {
                let mut angles: Vec<f64> = chosen.iter().map(|&i| coverage.angles_deg[i]).collect();
                angles.push(coverage.angles_deg[c]);
                let clock = options.clock.capture_s(&angles, &ladder);
                if clock > options.budget_s {
                    return None;
                }
                let score = a_criterion(&w, &h + &per_candidate[c])?;
                Some((c, score, clock))
            })
            .min_by(|a, b| a.1.total_cmp(&b.1).then(a.0.cmp(&b.0)));
        let Some((c, score, clock)) = best else {
            break;
        };
        h += &per_candidate[c];
        let new_entries = coverage.entries[c]
            .iter()
            .filter(|&&e| !std::mem::replace(&mut reached[e as usize], true))
            .count();
        covered += new_entries;
        chosen.push(c);
        steps.push(PlanStep {
            angle_deg: coverage.angles_deg[c],
            entries: coverage.entries[c].len(),
            new_entries,
            covered_fraction: covered as f64 / full_count as f64,
            predicted_log_sd: (sigma2 * score.max(0.0) / full_count as f64).sqrt(),
            clock_s: clock,
        });
        tracing::debug!(
            angle = coverage.angles_deg[c],
            score,
            clock,
            "plan: position added"
        );
    }
    if chosen.is_empty() {
        return Err(FastError::InvalidOption(format!(
            "not one lamp position fits the clock budget of {} s (one position takes {:.1} s with these exposures)",
            options.budget_s,
            options.clock.capture_s(&[0.0], &ladder)
        )));
    }
    let mut angles_deg: Vec<f64> = chosen.iter().map(|&c| coverage.angles_deg[c]).collect();
    angles_deg.sort_by(f64::total_cmp);
    let eig = h.clone().symmetric_eigen().eigenvalues;
    let (lo, hi) = eig.iter().fold((f64::INFINITY, 0.0f64), |(lo, hi), &v| {
        (lo.min(v), hi.max(v))
    });
    Ok(CapturePlan {
        version: PLAN_VERSION,
        predicted_clock_s: options.clock.capture_s(&angles_deg, &ladder),
        angles_deg,
        steps,
        exposures_s: ladder,
        full_entries: full_list.len(),
        covered_entries: covered,
        residual_log_var: sigma2,
        condition: hi / lo.max(1e-300),
        model_materials: pca.coords.nrows(),
        options: options.clone(),
    })
}

/// The same number of positions spread evenly over the candidates (the plan's baseline in the
/// study): `count` angles of [`gantry_hal::position_angles`].
pub fn even_angles(count: usize) -> Vec<f64> {
    gantry_hal::position_angles(count)
}
