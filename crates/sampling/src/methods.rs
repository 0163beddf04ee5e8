//! One entry point per CLI verb: [`plan`] and [`reconstruct`].

use rand::seq::index::sample;
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;

use crate::error::{Result, SamplingError};
use crate::grid::{GridTable, SampleGrid};
use crate::lincomb::{self, RowWeights, SearchBasis, SwapSearch};
use crate::logpca::LogPcaModel;
use crate::plan::{Measurements, Plan, SamplePoint};
use crate::pullpush::{pull_push, Domain};
use crate::training::{point_of, row_of, TrainingSet};
use crate::wavelet_pattern::{CoarseGrid, WaveletPatternModel};

/// Which equations `Y c ≈ b` of the linear combination are fitted and conditioned.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Equations {
    /// The values as measured (1/sr), as in the thesis: the least-squares fit minimises the
    /// absolute error, which the specular peaks dominate.
    #[default]
    Absolute,
    /// Each equation divided by the corpus mean of its row plus 10⁻³ (relative error), so that
    /// dim and bright configurations count alike: best for rendered appearance.
    Relative,
}

/// Variant of the linear-combination method (§6.5).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct LinCombOptions {
    /// Equations fitted.
    pub equations: Equations,
    /// Coordinates of the swap search's conditioning criterion.
    pub basis: SearchBasis,
}

impl LinCombOptions {
    /// The row weights of these equations for a training set.
    pub fn weights(&self, training: &TrainingSet) -> RowWeights {
        match self.equations {
            Equations::Absolute => RowWeights::Unit,
            Equations::Relative => RowWeights::relative(training),
        }
    }
}

/// Acquisition method, parsed from the names the commands take.
///
/// # Examples
///
/// ```
/// use sampling::Method;
///
/// assert_eq!("wavelet".parse::<Method>().unwrap(), Method::Wavelet);
/// assert_eq!("pull-push".parse::<Method>().unwrap(), Method::PullPush);
/// assert!(matches!("lincomb-relative".parse::<Method>().unwrap(), Method::LinComb(_)));
/// assert!("nearest".parse::<Method>().is_err());
/// ```
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Method {
    /// Linear combination of training materials (§6.5). Named `lincomb` (the thesis's: absolute
    /// equations, conditioning in material coordinates), `lincomb-whitened` (absolute
    /// equations, conditioning in corpus-whitened coordinates with leverage-drawn proposals)
    /// and `lincomb-relative` (relative equations).
    LinComb(LinCombOptions),
    /// Log-space PCA with A-optimal sample rows (beyond the thesis).
    Pca,
    /// Pull-push interpolation (§6.4). With a wavelet model it uses the wavelet pattern's
    /// points (as the thesis does); otherwise a seeded uniform random plan.
    PullPush,
    /// Common-Wavelet-Basis pattern and sparse solve (§6.3).
    Wavelet,
}

impl std::str::FromStr for Method {
    type Err = SamplingError;
    fn from_str(s: &str) -> Result<Self> {
        match s {
            "lincomb" => Ok(Method::LinComb(LinCombOptions::default())),
            "lincomb-whitened" => Ok(Method::LinComb(LinCombOptions {
                equations: Equations::Absolute,
                basis: SearchBasis::Whitened,
            })),
            "lincomb-relative" => Ok(Method::LinComb(LinCombOptions {
                equations: Equations::Relative,
                basis: SearchBasis::Materials,
            })),
            "pca" => Ok(Method::Pca),
            "pullpush" | "pull-push" => Ok(Method::PullPush),
            "wavelet" => Ok(Method::Wavelet),
            other => Err(SamplingError::InvalidParameter(format!(
                "unknown method `{other}` (lincomb, lincomb-whitened, lincomb-relative, pca, \
                 pullpush, wavelet)"
            ))),
        }
    }
}

/// What a method needs besides the measurements.
#[derive(Debug, Clone)]
pub enum Model {
    /// The training corpus itself (linear combination).
    LinComb(TrainingSet),
    /// A log-space PCA model.
    LogPca(LogPcaModel),
    /// Only a grid (pull-push).
    Grid(SampleGrid),
    /// A Common Wavelet Basis.
    Wavelet(WaveletPatternModel),
}

impl Model {
    /// The training corpus of a linear-combination model.
    pub fn lincomb_training(&self) -> Option<&TrainingSet> {
        match self {
            Model::LinComb(t) => Some(t),
            _ => None,
        }
    }

    /// The grid reconstructions live on.
    pub fn grid(&self) -> SampleGrid {
        match self {
            Model::LinComb(t) => t.grid,
            Model::LogPca(m) => m.grid,
            Model::Grid(g) => *g,
            Model::Wavelet(w) => w.grid,
        }
    }
}

/// Settings of [`plan`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PlanOptions {
    /// Seed of every random choice.
    pub seed: u64,
    /// Proposals of the linear-combination swap search.
    pub swap_proposals: usize,
}

/// Settings of the wavelet solve.
pub const WAVELET_CGLS_ITERATIONS: usize = 400;
/// Damping of the wavelet solve (relative to unit-norm Haar rows).
pub const WAVELET_DAMPING: f64 = 1e-3;

impl Default for PlanOptions {
    fn default() -> Self {
        PlanOptions {
            seed: 1,
            swap_proposals: 2000,
        }
    }
}

/// The plan measuring the given rows (`channel × grid.len() + point`) of `grid`, in order.
pub fn plan_from_rows(grid: &SampleGrid, rows: &[usize]) -> Plan {
    Plan {
        points: rows
            .iter()
            .map(|&r| {
                let (p, c) = point_of(grid, r);
                SamplePoint::at_grid(grid, p, c)
            })
            .collect(),
    }
}

/// `n` distinct (grid point, channel) rows drawn uniformly with a seeded generator, only
/// among configurations with both directions above the horizon.
pub fn uniform_plan(grid: &SampleGrid, n: usize, seed: u64) -> Result<Plan> {
    let candidates: Vec<usize> = (0..3 * grid.len())
        .filter(|&r| {
            let (th, td, pd) = grid.angles(point_of(grid, r).0);
            brdf::HalfDiff::isotropic(th, td, pd).above_horizon()
        })
        .collect();
    if n == 0 || n > candidates.len() {
        return Err(SamplingError::InvalidParameter(format!(
            "cannot draw {n} of {} rows",
            candidates.len()
        )));
    }
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let mut rows: Vec<usize> = sample(&mut rng, candidates.len(), n)
        .into_iter()
        .map(|i| candidates[i])
        .collect();
    rows.sort_unstable();
    Ok(plan_from_rows(grid, &rows))
}

/// The `n` points to measure with `method`.
pub fn plan(method: Method, n: usize, model: &Model, options: PlanOptions) -> Result<Plan> {
    match (method, model) {
        (Method::LinComb(o), Model::LinComb(t)) => {
            let sel = lincomb::select_rows_weighted(
                t,
                n,
                SwapSearch {
                    proposals: options.swap_proposals,
                    seed: options.seed,
                    basis: o.basis,
                },
                &o.weights(t),
            )?;
            Ok(plan_from_rows(&t.grid, &sel.rows))
        }
        (Method::Pca, Model::LogPca(m)) => {
            let (rows, _) = m.select_rows(n)?;
            Ok(plan_from_rows(&m.grid, &rows))
        }
        (Method::Wavelet | Method::PullPush, Model::Wavelet(w)) => {
            // n = 0: one point per CWB function (3 channels each). Otherwise about n / 3
            // points, chosen coarse to fine (fewer: the finest functions go without; more:
            // further passes over the basis).
            let oversample = if n == 0 {
                1.0
            } else {
                n as f64 / (3 * w.len().max(1)) as f64
            };
            let pts = w.select_points(oversample, options.seed)?;
            let rows: Vec<usize> = pts
                .iter()
                .flat_map(|&p| (0..3).map(move |c| (p, c)))
                .map(|(p, c)| row_of(&w.grid, p, c))
                .collect();
            Ok(plan_from_rows(&w.grid, &rows))
        }
        (Method::PullPush, m) => uniform_plan(&m.grid(), n, options.seed),
        (method, _) => Err(SamplingError::InvalidParameter(format!(
            "method {method:?} needs a different model"
        ))),
    }
}

/// Reconstructs a table on the model grid from measured values (points snap to the nearest
/// grid point).
pub fn reconstruct(
    method: Method,
    measurements: &Measurements,
    model: &Model,
) -> Result<GridTable> {
    let grid = model.grid();
    let rows: Vec<usize> = measurements
        .plan()
        .rows(&grid)
        .into_iter()
        .map(|(p, c)| row_of(&grid, p, c))
        .collect();
    match (method, model) {
        (Method::LinComb(o), Model::LinComb(t)) => {
            let c =
                lincomb::fit_coefficients_weighted(t, &rows, &measurements.values, &o.weights(t))?;
            lincomb::combine(t, &c)
        }
        (Method::Pca, Model::LogPca(m)) => {
            let a = m.fit_coefficients(&rows, &measurements.values)?;
            m.reconstruct(&a)
        }
        (Method::Wavelet, Model::Wavelet(w)) => {
            let samples = measurements.grid_samples(&grid);
            let coarse = CoarseGrid::for_cube(w.basis.layout().side);
            w.reconstruct(
                &samples,
                WAVELET_CGLS_ITERATIONS,
                WAVELET_DAMPING,
                Some(coarse),
            )
        }
        (Method::PullPush, _) => {
            let samples = measurements.grid_samples(&grid);
            pull_push(&grid, &samples, Domain::Log)
        }
        (method, _) => Err(SamplingError::InvalidParameter(format!(
            "method {method:?} needs a different model"
        ))),
    }
}

/// Default number of log-PCA components.
pub const DEFAULT_PCA_COMPONENTS: usize = 40;
/// Default relative-error target of the Common Wavelet Basis (the thesis's 3 %).
pub const DEFAULT_CWB_TARGET: f64 = 0.03;

/// Builds the model `method` needs from a training set: the set itself (lincomb), a log-PCA
/// model with `DEFAULT_PCA_COMPONENTS` (capped at N − 1) and measurement noise `noise`, a
/// CWB at `DEFAULT_CWB_TARGET` (wavelet), or just the grid (pull-push).
pub fn build_model(method: Method, training: TrainingSet, noise: f64) -> Result<Model> {
    Ok(match method {
        Method::LinComb(_) => Model::LinComb(training),
        Method::Pca => {
            let k = DEFAULT_PCA_COMPONENTS.min(training.len().saturating_sub(1));
            Model::LogPca(LogPcaModel::fit(&training, k, noise)?)
        }
        Method::Wavelet => {
            Model::Wavelet(WaveletPatternModel::build(&training, DEFAULT_CWB_TARGET)?)
        }
        Method::PullPush => Model::Grid(training.grid),
    })
}
