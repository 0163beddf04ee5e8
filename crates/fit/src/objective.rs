//! Objectives: residuals, their exact Jacobian and the normal equations.

use crate::data::{FitData, Rows, Subset, LOG_FLOOR};
use crate::dual::{Dual, Real};
use crate::error::{FitError, Result};
use crate::model::{Model, ModelKind, Parametric};
use brdf::analytic::Analytic;
use rayon::prelude::*;

/// What a fit minimises. Residuals and their exact Jacobian (forward-mode differentiation of
/// the model) feed normal equations accumulated in parallel, without storing the Jacobian.
///
/// # Examples
///
/// ```
/// use fit::{FitData, Objective, Subset};
/// let data = FitData::new(&brdf::load("lambert:kd=0.5").unwrap().tabulate()).unwrap();
/// for objective in Objective::ALL {
///     assert_eq!(Objective::parse(objective.name()).unwrap(), objective);
/// }
/// // The log objective uses one row per selected bin; the sphere objective ignores the subset.
/// let subset = Subset::Random { bins: 500, seed: 3 };
/// assert_eq!(Objective::Log.rows(&data, subset).unwrap().len(), 500);
/// let sphere = Objective::Sphere.rows(&data, subset).unwrap();
/// assert!(sphere.len() > 500 && sphere.len() <= data.sphere_size * data.sphere_size);
/// // The true parameters leave no residual.
/// let rows = Objective::Log.rows(&data, subset).unwrap();
/// let p = fit::ModelKind::Lambert.to_solver(&[0.5, 0.5, 0.5]);
/// let r = fit::residuals(fit::ModelKind::Lambert, &rows, &p);
/// assert!(r.iter().all(|x| x.abs() < 1e-6));
/// ```
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord, serde::Serialize)]
pub enum Objective {
    /// Thesis §3.7: squared differences of ln(f + 10⁻³), bins unweighted.
    Log,
    /// Ngan et al. 2005: cosine-weighted, solid-angle-weighted L2 of ρ cos θi, θ ≤ 80°.
    Ngan,
    /// The sampling crate's rendered-sphere image difference (four point lights).
    Sphere,
}

impl Objective {
    /// All objectives.
    pub const ALL: [Objective; 3] = [Objective::Log, Objective::Ngan, Objective::Sphere];

    /// Name on the command line.
    pub fn name(self) -> &'static str {
        match self {
            Objective::Log => "log",
            Objective::Ngan => "ngan",
            Objective::Sphere => "sphere",
        }
    }

    /// Parses `log`, `ngan` or `sphere`.
    pub fn parse(s: &str) -> Result<Objective> {
        match s.to_ascii_lowercase().as_str() {
            "log" => Ok(Objective::Log),
            "ngan" => Ok(Objective::Ngan),
            "sphere" => Ok(Objective::Sphere),
            other => Err(FitError::UnknownObjective(other.into())),
        }
    }

    /// The rows of this objective on `data` (the sphere objective ignores `subset`: it always
    /// uses every lit pixel).
    pub fn rows(self, data: &FitData, subset: Subset) -> Result<Rows> {
        match self {
            Objective::Log => Rows::log(data, subset),
            Objective::Ngan => Rows::ngan(data, subset),
            Objective::Sphere => Rows::sphere(data),
        }
    }
}

/// The normal equations of the linearised problem at one point: JᵀJ, Jᵀr and rᵀr.
#[derive(Debug, Clone, PartialEq)]
pub struct Normal {
    /// JᵀJ, row-major `dim × dim`.
    pub jtj: Vec<f64>,
    /// Jᵀr.
    pub jtr: Vec<f64>,
    /// rᵀr.
    pub rtr: f64,
}

#[inline]
fn residuals_of_row<T: Real>(model: &Model<T>, rows: &Rows, r: usize) -> [T; 3] {
    let (a, b) = (rows.row_start[r] as usize, rows.row_start[r + 1] as usize);
    let mut pred = [T::cst(0.0); 3];
    for t in a..b {
        let g = &rows.geoms[rows.term_geom[t] as usize];
        let f = model.value(g);
        let w = rows.term_weight[t];
        for c in 0..3 {
            pred[c] = pred[c] + f[c] * w;
        }
    }
    let target = rows.targets[r];
    let mut out = [T::cst(0.0); 3];
    for c in 0..3 {
        out[c] = if rows.log {
            let x = if pred[c].val() > 0.0 {
                pred[c] + LOG_FLOOR
            } else {
                T::cst(LOG_FLOOR)
            };
            x.ln() - target[c]
        } else {
            pred[c] - target[c]
        };
    }
    out
}

/// Residuals at solver vector `p`, three per row (channel-minor).
pub fn residuals(kind: ModelKind, rows: &Rows, p: &[f64]) -> Vec<f64> {
    let model = kind.model(&kind.to_model(p));
    (0..rows.len())
        .into_par_iter()
        .flat_map_iter(|r| residuals_of_row(&model, rows, r))
        .collect()
}

/// The relative error of model parameters `q` on `rows`: √(Σ r² / norm²).
pub fn relative_error(kind: ModelKind, rows: &Rows, q: &[f64]) -> f64 {
    // Per-row sums collected in order, then summed sequentially: the same bits on every
    // run, whatever the thread scheduling.
    let model = kind.model(q);
    let per_row: Vec<f64> = (0..rows.len())
        .into_par_iter()
        .map(|r| {
            residuals_of_row(&model, rows, r)
                .iter()
                .map(|x| x * x)
                .sum::<f64>()
        })
        .collect();
    let s: f64 = per_row.iter().sum();
    (s / rows.norm2).sqrt()
}

/// The Jacobian of [`residuals`] with respect to the solver vector, row-major (3·rows × dim).
pub fn jacobian(kind: ModelKind, rows: &Rows, p: &[f64]) -> Vec<f64> {
    let dim = p.len();
    macro_rules! go {
        ($n:literal) => {{
            let pd: Vec<Dual<$n>> = p
                .iter()
                .enumerate()
                .map(|(i, v)| Dual::var(*v, i))
                .collect();
            let model = kind.model(&kind.to_model(&pd));
            (0..rows.len())
                .into_par_iter()
                .flat_map_iter(|r| {
                    let res = residuals_of_row(&model, rows, r);
                    res.into_iter()
                        .flat_map(move |x| x.d.into_iter().take(dim).collect::<Vec<_>>())
                })
                .collect()
        }};
    }
    match dim {
        0..=4 => go!(4),
        5..=8 => go!(8),
        // the two-lobe models and He-Torrance-Sillion-Greenberg: a 16-wide dual number would
        // carry 4 to 7 partials that are always zero
        9..=12 => go!(12),
        _ => go!(16),
    }
}

/// The normal equations at solver vector `p`, accumulated over the rows in parallel.
pub fn normal_equations(kind: ModelKind, rows: &Rows, p: &[f64]) -> Normal {
    macro_rules! go {
        ($n:literal) => {
            accumulate::<$n>(kind, rows, p)
        };
    }
    match p.len() {
        0..=4 => go!(4),
        5..=8 => go!(8),
        // the two-lobe models and He-Torrance-Sillion-Greenberg: a 16-wide dual number would
        // carry 4 to 7 partials that are always zero
        9..=12 => go!(12),
        _ => go!(16),
    }
}

fn accumulate<const N: usize>(kind: ModelKind, rows: &Rows, p: &[f64]) -> Normal {
    let dim = p.len();
    let pd: Vec<Dual<N>> = p
        .iter()
        .enumerate()
        .map(|(i, v)| Dual::var(*v, i))
        .collect();
    let model = kind.model(&kind.to_model(&pd));
    let zero = || Normal {
        jtj: vec![0.0; dim * dim],
        jtr: vec![0.0; dim],
        rtr: 0.0,
    };
    // Fixed groups of rows folded in parallel and combined in order, so that a fit is
    // bitwise reproducible (rayon's own fold splits where threads steal work).
    let parts: Vec<Normal> = (0..rows.len())
        .into_par_iter()
        .fold_chunks(256, zero, |mut acc, r| {
            for x in residuals_of_row(&model, rows, r) {
                acc.rtr += x.v * x.v;
                for i in 0..dim {
                    let di = x.d[i];
                    if di == 0.0 {
                        continue;
                    }
                    acc.jtr[i] += di * x.v;
                    let row = &mut acc.jtj[i * dim..(i + 1) * dim];
                    for j in 0..=i {
                        row[j] += di * x.d[j];
                    }
                }
            }
            acc
        })
        .collect();
    parts
        .into_iter()
        .fold(zero(), |mut a, b| {
            a.rtr += b.rtr;
            for (x, y) in a.jtr.iter_mut().zip(&b.jtr) {
                *x += y;
            }
            for (x, y) in a.jtj.iter_mut().zip(&b.jtj) {
                *x += y;
            }
            a
        })
        .symmetrised(dim)
}

impl Normal {
    fn symmetrised(mut self, dim: usize) -> Normal {
        for i in 0..dim {
            for j in 0..i {
                self.jtj[j * dim + i] = self.jtj[i * dim + j];
            }
        }
        self
    }
}

/// Errors of a fitted model in the three metrics, each on every valid bin (log, Ngan) or every
/// lit pixel (sphere).
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct Errors {
    /// Relative RMS error in log space (thesis §3.7; `sampling::metrics::log_rms_relative`).
    pub log: f64,
    /// Relative cosine-weighted L2 error (Ngan et al. 2005).
    pub ngan: f64,
    /// Relative RMS error of the rendered sphere (`sampling::metrics::image_rms_relative`).
    pub sphere: f64,
}

/// The evaluation rows of a table: every valid bin for the log and Ngan metrics, every lit
/// pixel for the sphere metric. Build once per table and reuse for every model.
#[derive(Debug, Clone)]
pub struct EvalRows {
    /// Log-space rows.
    pub log: Rows,
    /// Ngan rows.
    pub ngan: Rows,
    /// Sphere rows.
    pub sphere: Rows,
}

impl EvalRows {
    /// Builds the three row sets on all valid bins.
    pub fn new(data: &FitData) -> Result<EvalRows> {
        Self::with_subset(data, Subset::All)
    }

    /// Builds the log and Ngan rows on a subset of the valid bins (the sphere rows always use
    /// every lit pixel).
    pub fn with_subset(data: &FitData, subset: Subset) -> Result<EvalRows> {
        Ok(EvalRows {
            log: Rows::log(data, subset)?,
            ngan: Rows::ngan(data, subset)?,
            sphere: Rows::sphere(data)?,
        })
    }

    /// The errors of a model.
    pub fn errors(&self, model: &Parametric) -> Errors {
        Errors {
            log: relative_error(model.kind, &self.log, &model.q),
            ngan: relative_error(model.kind, &self.ngan, &model.q),
            sphere: relative_error(model.kind, &self.sphere, &model.q),
        }
    }

    /// The rows of one objective.
    pub fn get(&self, objective: Objective) -> &Rows {
        match objective {
            Objective::Log => &self.log,
            Objective::Ngan => &self.ngan,
            Objective::Sphere => &self.sphere,
        }
    }
}

/// Readings of the thesis's "error calculated in log space" (§3.7), which the thesis does not
/// define further; each over every valid bin and channel with a positive measured value.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct LogReadings {
    /// √(Σ (ln f̂ − ln f)² / Σ (ln f)²): relative RMS of the plain natural logarithm (the thesis
    /// applies ln without an offset in §4.1).
    pub plain_relative: f64,
    /// Σ |ln f̂ − ln f| / Σ |ln f|: relative mean absolute error of the plain logarithm.
    pub mean_abs_relative: f64,
    /// √(mean (ln f̂ − ln f)²): RMS of the log ratio, ≈ the RMS relative error of the values.
    pub rms_log_ratio: f64,
    /// Number of channel values used (measured value > 0 and model value > 0).
    pub values: usize,
    /// Channel values left out because the model is 0 there (ln undefined).
    pub model_zero: usize,
}

/// The [`LogReadings`] of `model` on every valid bin of `data`.
pub fn log_readings(data: &FitData, model: &Parametric) -> LogReadings {
    let geoms = &crate::data::grid_geometry().geoms;
    let m = model.kind.model(&model.q);
    let (num, den, n, zero, abs_num, abs_den) = data
        .entries
        .par_iter()
        .zip(&data.values)
        .map(|(e, f)| {
            let m: [f64; 3] = m.value(&geoms[*e as usize]);
            let mut acc = (0.0, 0.0, 0usize, 0usize, 0.0, 0.0);
            for c in 0..3 {
                if f[c] <= 0.0 {
                    continue;
                }
                if m[c] <= 0.0 {
                    acc.3 += 1;
                    continue;
                }
                let d = m[c].ln() - f[c].ln();
                acc.0 += d * d;
                acc.1 += f[c].ln().powi(2);
                acc.2 += 1;
                acc.4 += d.abs();
                acc.5 += f[c].ln().abs();
            }
            acc
        })
        .reduce(
            || (0.0, 0.0, 0, 0, 0.0, 0.0),
            |a, b| {
                (
                    a.0 + b.0,
                    a.1 + b.1,
                    a.2 + b.2,
                    a.3 + b.3,
                    a.4 + b.4,
                    a.5 + b.5,
                )
            },
        );
    LogReadings {
        plain_relative: if den > 0.0 {
            (num / den).sqrt()
        } else {
            f64::NAN
        },
        mean_abs_relative: if abs_den > 0.0 {
            abs_num / abs_den
        } else {
            f64::NAN
        },
        rms_log_ratio: if n > 0 {
            (num / n as f64).sqrt()
        } else {
            f64::NAN
        },
        values: n,
        model_zero: zero,
    }
}
