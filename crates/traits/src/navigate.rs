//! Navigation in the linear and chart spaces, keeping every result physically valid.

use nalgebra::{DMatrix, DVector};
use rayon::prelude::*;
use reduce::Model;
use reduce::LOG_FLOOR;
use serde::{Deserialize, Serialize};

use crate::direction::{Direction, Method};
use crate::error::{Result, TraitsError};
use crate::select::RidgeVariant;
use crate::validity::{
    hull_line_search, max_albedo, validate, AlbedoQuadrature, Check, ValidityOptions,
    ValidityReport,
};
use brdf::BINS;

/// Steps of the chart-space march before bisection.
pub const CHART_MARCH_STEPS: usize = 6;
/// Bisection steps when locating a border.
pub const BISECTION_STEPS: usize = 24;
/// Default number of PCA coordinates of the linear space (the thesis's 45).
pub const LINEAR_DIM: usize = 45;

/// The embedding a trait lives in.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Space {
    /// The first `k` PCA coordinates of the log-space corpus.
    Linear,
    /// The charting embedding (thesis §4.4).
    Chart,
}

impl std::str::FromStr for Space {
    type Err = TraitsError;
    fn from_str(s: &str) -> Result<Space> {
        match s {
            "linear" => Ok(Space::Linear),
            "chart" => Ok(Space::Chart),
            o => Err(TraitsError::InvalidParameter(format!(
                "space {o:?} (linear or chart)"
            ))),
        }
    }
}

/// One named trait vector.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct TraitVector {
    /// Trait name.
    pub name: String,
    /// The calibrated direction.
    pub direction: Direction,
    /// Cross-validated agreement with the labels (sign accuracy for binary traits, Spearman ρ
    /// for rated ones), when measured.
    pub cross_validated: Option<f64>,
    /// For a rated trait fitted by the default selection, the ridge variant it chose.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub variant: Option<RidgeVariant>,
}

/// A set of traits fitted in one space with one method (the `traits.json` file).
///
/// # Examples
///
/// ```
/// use nalgebra::DMatrix;
/// use traits::{fit_binary, FitOptions, Method, Space, TraitSet, TraitVector};
/// // Four materials in a 2-D space: "bright" where the first coordinate is large.
/// let x = DMatrix::from_row_slice(4, 2, &[2.0, 0.1, 3.0, -0.2, -1.0, 0.3, -2.0, 0.0]);
/// let bright = fit_binary(&x, &[true, true, false, false], Method::Mean, &FitOptions::default());
/// let set = TraitSet {
///     space: Space::Linear,
///     dim: 2,
///     method: Method::Mean,
///     traits: vec![TraitVector {
///         name: "bright".into(),
///         direction: bright.unwrap(),
///         cross_validated: None,
///         variant: None,
///     }],
/// };
/// let dir = tempfile::tempdir().unwrap();
/// let path = dir.path().join("traits.json");
/// set.save(&path).unwrap();
/// let back = TraitSet::load(&path).unwrap();
/// assert_eq!(back, set);
/// assert!(back.get("bright").unwrap().direction.score(&[2.5, 0.0]) > 0.5);
/// assert!(back.get("red").is_err());
/// ```
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct TraitSet {
    /// Space of the directions.
    pub space: Space,
    /// Dimension of the space.
    pub dim: usize,
    /// Method used.
    pub method: Method,
    /// The traits.
    pub traits: Vec<TraitVector>,
}

impl TraitSet {
    /// The trait with this name.
    pub fn get(&self, name: &str) -> Result<&TraitVector> {
        self.traits
            .iter()
            .find(|t| t.name == name)
            .ok_or_else(|| TraitsError::UnknownTrait(name.into()))
    }

    /// Writes the set as JSON, atomically.
    pub fn save(&self, path: impl AsRef<std::path::Path>) -> Result<()> {
        let p = path.as_ref();
        let json = serde_json::to_vec_pretty(self)?;
        brdf::write_atomic(p, &json).map_err(TraitsError::from)
    }

    /// Reads a set written by [`TraitSet::save`].
    pub fn load(path: impl AsRef<std::path::Path>) -> Result<TraitSet> {
        let p = path.as_ref();
        let text = std::fs::read(p).map_err(|e| TraitsError::io(p, e))?;
        Ok(serde_json::from_slice(&text)?)
    }
}

/// Coordinates of materials in one of the model's spaces.
#[derive(Debug, Clone, Copy)]
pub struct Embedding<'m> {
    /// The model.
    pub model: &'m Model,
    /// The space.
    pub space: Space,
    /// PCA coordinates used (linear: the space's dimension; chart: the chart's ambient
    /// dimension).
    pub pca_dim: usize,
    /// Chart space: how far, in the corpus's standard deviations, a back-projected PCA
    /// coefficient may leave the corpus's range along its axis (`None`: no limit). The
    /// default is [`CHART_PCA_MARGIN`]; the linear space ignores it.
    pub pca_margin: Option<f64>,
}

/// The default [`Embedding::pca_margin`] of the chart space. The chart's back-projection
/// (2.54) mixes local linear maps, and far from the corpus it moves the higher principal
/// coefficients by many times the corpus's spread along them; those basis functions
/// oscillate along θh and draw rings around highlights. Coefficients are therefore kept
/// within the corpus's range along each axis, widened by this many standard deviations
/// (the corpus's own points lie inside, so their back-projection is unchanged).
pub const CHART_PCA_MARGIN: f64 = 1.0;

impl<'m> Embedding<'m> {
    /// The embedding of `space`; `linear_dim` PCA coordinates for the linear space.
    pub fn new(model: &'m Model, space: Space, linear_dim: usize) -> Result<Embedding<'m>> {
        model.require_log_mapping("trait navigation")?;
        let pca_dim = match space {
            Space::Linear => {
                if linear_dim == 0 || linear_dim > model.components() {
                    return Err(TraitsError::InvalidParameter(format!(
                        "linear dimension {linear_dim} (model has {})",
                        model.components()
                    )));
                }
                linear_dim
            }
            Space::Chart => model
                .chart
                .as_ref()
                .ok_or(TraitsError::MissingModelPart("chart"))?
                .charts
                .ambient_dim(),
        };
        Ok(Embedding {
            model,
            space,
            pca_dim,
            pca_margin: Some(CHART_PCA_MARGIN),
        })
    }

    /// Dimension of the space.
    pub fn dim(&self) -> usize {
        match self.space {
            Space::Linear => self.pca_dim,
            Space::Chart => self.model.chart.as_ref().map_or(0, |c| c.dim),
        }
    }

    /// Coordinates of the corpus materials, `N × dim`.
    pub fn corpus(&self) -> Result<DMatrix<f64>> {
        match self.space {
            Space::Linear => Ok(self.model.pca.coords.columns(0, self.pca_dim).into_owned()),
            Space::Chart => Ok(self
                .model
                .chart
                .as_ref()
                .ok_or(TraitsError::MissingModelPart("chart"))?
                .embedding()?),
        }
    }

    /// Coordinates of a corpus material by name.
    pub fn of_name(&self, name: &str) -> Result<Vec<f64>> {
        let i = self
            .model
            .names
            .iter()
            .position(|n| n == name)
            .ok_or_else(|| TraitsError::UnknownMaterial(name.into()))?;
        self.from_pca(self.model.pca.coords.row(i).iter().copied().collect())
    }

    /// Coordinates of any material given by its BRDF values (projected first).
    pub fn project_values(&self, values: &[f64]) -> Result<Vec<f64>> {
        let c = self.model.project_values(values, self.pca_dim)?;
        self.from_pca(c)
    }

    /// Coordinates of the PCA coefficient vector `c` (at least `pca_dim` long).
    pub fn from_pca(&self, mut c: Vec<f64>) -> Result<Vec<f64>> {
        if c.len() < self.pca_dim {
            return Err(TraitsError::Dimension {
                what: "PCA coefficients",
                expected: self.pca_dim,
                got: c.len(),
            });
        }
        c.truncate(self.pca_dim);
        match self.space {
            Space::Linear => Ok(c),
            Space::Chart => Ok(self
                .chart()?
                .forward(&DVector::from_vec(c))?
                .iter()
                .copied()
                .collect()),
        }
    }

    /// The model's chart, which the chart space needs.
    fn chart(&self) -> Result<&reduce::Chart> {
        self.model
            .chart
            .as_ref()
            .ok_or(TraitsError::MissingModelPart("chart"))
    }

    /// PCA coefficients of a point of the space (back-projection (2.54) for the chart, each
    /// coefficient kept within the corpus's range widened by [`Embedding::pca_margin`]).
    pub fn to_pca(&self, x: &[f64]) -> Result<Vec<f64>> {
        if x.len() != self.dim() {
            return Err(TraitsError::Dimension {
                what: "space coordinates",
                expected: self.dim(),
                got: x.len(),
            });
        }
        match self.space {
            Space::Linear => Ok(x.to_vec()),
            Space::Chart => {
                let mut c = self.chart()?.backward_vec(x)?;
                if let Some(m) = self.pca_margin {
                    self.limit_to_corpus(&mut c, m);
                }
                Ok(c)
            }
        }
    }

    /// Clamps each PCA coefficient to the corpus's range along its axis, widened by `margin`
    /// standard deviations of the corpus.
    fn limit_to_corpus(&self, c: &mut [f64], margin: f64) {
        let coords = &self.model.pca.coords;
        let n = coords.nrows() as f64;
        for (j, v) in c.iter_mut().enumerate().take(coords.ncols()) {
            let col = coords.column(j);
            let mean = col.mean();
            let sd = (col.iter().map(|a| (a - mean).powi(2)).sum::<f64>() / n).sqrt();
            *v = v.clamp(col.min() - margin * sd, col.max() + margin * sd);
        }
    }
}

/// Log-space back-projection `m + U c` of the first `c.len()` components, parallel over
/// blocks, accumulated in 8 lanes (vectorisable).
pub fn reconstruct_log(model: &Model, c: &[f64]) -> Result<Vec<f32>> {
    let p = &model.pca;
    if c.len() > p.components {
        return Err(TraitsError::Dimension {
            what: "PCA coefficients",
            expected: p.components,
            got: c.len(),
        });
    }
    if c.iter().any(|v| !v.is_finite()) {
        return Err(TraitsError::Numerical("non-finite coefficients".into()));
    }
    let kk = p.components;
    let k = c.len();
    let mut xf = [0.0f32; 64];
    let lanes = k.div_ceil(8) * 8;
    if lanes > 64 {
        // Fall back to the model's own reconstruction for very wide models.
        return Ok(p.reconstruct(c)?);
    }
    for (a, b) in xf.iter_mut().zip(c) {
        *a = *b as f32;
    }
    let mut out = p.mean.clone();
    const BLOCK: usize = 4096;
    out.par_chunks_mut(BLOCK).enumerate().for_each(|(blk, o)| {
        let d0 = blk * BLOCK;
        for (j, v) in o.iter_mut().enumerate() {
            let row = &p.basis[(d0 + j) * kk..(d0 + j) * kk + k];
            let mut acc = [0.0f32; 8];
            let mut chunks = row.chunks_exact(8);
            let mut xc = xf.chunks_exact(8);
            for r in chunks.by_ref() {
                let x = xc.next().unwrap_or(&[0.0; 8]);
                for l in 0..8 {
                    acc[l] += r[l] * x[l];
                }
            }
            let rem = chunks.remainder();
            let base = k - rem.len();
            for (l, r) in rem.iter().enumerate() {
                acc[l] += r * xf[base + l];
            }
            *v += acc.iter().sum::<f32>();
        }
    });
    Ok(out)
}

/// The log-space back-projection `m + U c` and the direction `U d` in one pass over the basis
/// (`c` and `d` of the same length): the start of a linear edit and its move.
pub fn reconstruct_log_pair(model: &Model, c: &[f64], d: &[f64]) -> Result<(Vec<f32>, Vec<f32>)> {
    let p = &model.pca;
    if c.len() > p.components || d.len() != c.len() {
        return Err(TraitsError::Dimension {
            what: "PCA coefficients",
            expected: c.len().min(p.components),
            got: d.len(),
        });
    }
    if c.iter().chain(d).any(|v| !v.is_finite()) {
        return Err(TraitsError::Numerical("non-finite coefficients".into()));
    }
    let kk = p.components;
    let k = c.len();
    let cf: Vec<f32> = c.iter().map(|&v| v as f32).collect();
    let df: Vec<f32> = d.iter().map(|&v| v as f32).collect();
    let mut y = p.mean.clone();
    let mut dy = vec![0.0f32; p.mean.len()];
    const BLOCK: usize = 4096;
    y.par_chunks_mut(BLOCK)
        .zip(dy.par_chunks_mut(BLOCK))
        .enumerate()
        .for_each(|(blk, (yo, dyo))| {
            let d0 = blk * BLOCK;
            for (j, (yv, dv)) in yo.iter_mut().zip(dyo.iter_mut()).enumerate() {
                let row = &p.basis[(d0 + j) * kk..(d0 + j) * kk + k];
                let mut a = [0.0f32; 8];
                let mut b = [0.0f32; 8];
                let mut rc = row.chunks_exact(8);
                for ((r, x), z) in rc.by_ref().zip(cf.chunks_exact(8)).zip(df.chunks_exact(8)) {
                    for l in 0..8 {
                        a[l] += r[l] * x[l];
                        b[l] += r[l] * z[l];
                    }
                }
                let base = k - rc.remainder().len();
                for (l, r) in rc.remainder().iter().enumerate() {
                    a[l] += r * cf[base + l];
                    b[l] += r * df[base + l];
                }
                *yv += a.iter().sum::<f32>();
                *dv = b.iter().sum::<f32>();
            }
        });
    Ok((y, dy))
}

/// Basis rows at the bins the albedo quadrature reads: the albedo of a model point from its
/// PCA coefficients in `O(bins · k)`.
#[derive(Debug, Clone)]
struct SparseRows {
    /// Quadrature rules re-indexed into `rows`: `[θi] → (row index, weight)`.
    rules: Vec<Vec<(usize, f64)>>,
    /// For every distinct bin and channel (row `3·i + c`): mean and `k` basis entries.
    mean: Vec<f64>,
    basis: Vec<f64>,
    k: usize,
    /// The distinct bins, sorted.
    bins: Vec<usize>,
}

impl SparseRows {
    fn new(model: &Model, q: &AlbedoQuadrature, k: usize) -> SparseRows {
        let bins = q.bins();
        let kk = model.pca.components;
        let mut mean = Vec::with_capacity(bins.len() * 3);
        let mut basis = Vec::with_capacity(bins.len() * 3 * k);
        for &b in &bins {
            for c in 0..3 {
                let d = c * BINS + b;
                mean.push(model.pca.mean[d] as f64);
                basis.extend(
                    model.pca.basis[d * kk..d * kk + k]
                        .iter()
                        .map(|&v| v as f64),
                );
            }
        }
        let rules = q
            .rules
            .iter()
            .map(|r| {
                r.iter()
                    .map(|&(b, w)| (bins.binary_search(&b).unwrap_or(0), w))
                    .collect()
            })
            .collect();
        SparseRows {
            rules,
            mean,
            basis,
            k,
            bins,
        }
    }

    /// The quadrature's values along `y0 + t·scale·dy` (full log vectors).
    fn line(&self, y0: &[f32], dy: &[f32], scale: f32) -> SparseLine<'_> {
        let mut a = Vec::with_capacity(self.bins.len() * 3);
        let mut b = Vec::with_capacity(self.bins.len() * 3);
        for &bin in &self.bins {
            for c in 0..3 {
                a.push(y0[c * BINS + bin]);
                b.push(dy[c * BINS + bin] * scale);
            }
        }
        SparseLine {
            rules: &self.rules,
            y0: a,
            dy: b,
        }
    }

    /// Albedo `[θi][channel]` of the clamped back-projection of `c`.
    fn albedo(&self, c: &[f64]) -> Vec<[f64; 3]> {
        let k = self.k.min(c.len());
        let vals: Vec<f64> = (0..self.mean.len())
            .map(|r| {
                let row = &self.basis[r * self.k..r * self.k + k];
                let y = self.mean[r] + row.iter().zip(c).map(|(a, b)| a * b).sum::<f64>();
                // Same rounding as the written table: f32 log value.
                reduce::from_log(y as f32).max(0.0)
            })
            .collect();
        self.rules
            .iter()
            .map(|rule| {
                let mut a = [0.0; 3];
                for &(i, w) in rule {
                    for ch in 0..3 {
                        a[ch] += w * vals[3 * i + ch];
                    }
                }
                a
            })
            .collect()
    }
}

/// The values that the albedo quadrature reads, along the line `y(t) = y0 + t·dy`: gathered
/// once, so each evaluation is a few thousand exponentials.
struct SparseLine<'q> {
    rules: &'q [Vec<(usize, f64)>],
    y0: Vec<f32>,
    dy: Vec<f32>,
}

impl SparseLine<'_> {
    /// Largest albedo (over angles and channels) of the clamped table at `t`.
    fn max_albedo(&self, t: f32) -> f64 {
        let vals: Vec<f64> = self
            .y0
            .iter()
            .zip(&self.dy)
            .map(|(&y, &d)| reduce::from_log(y + t * d).max(0.0))
            .collect();
        let mut m = f64::NEG_INFINITY;
        for rule in self.rules {
            let mut a = [0.0; 3];
            for &(i, w) in rule {
                for ch in 0..3 {
                    a[ch] += w * vals[3 * i + ch];
                }
            }
            for v in a {
                if v > m || v.is_nan() {
                    m = v;
                }
            }
        }
        m
    }
}

/// Settings of a [`Navigator`].
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct NavigatorOptions {
    /// The checks of the written tables.
    pub validity: ValidityOptions,
    /// Back-projected values down to `−negative_tolerance` (1/sr) count as zero, not as a
    /// violation of non-negativity (the written table is clamped at 0, and
    /// [`EditOutcome::clamped`] counts them). The default is the model's floor
    /// ([`reduce::LOG_FLOOR`]): the back-projection `exp(y) − floor` never falls below
    /// `−floor`, so non-negativity never stops a move; a smaller tolerance makes it stop where
    /// a value falls below `−negative_tolerance`. See docs/traits.md.
    pub negative_tolerance: f64,
    /// Also keep the point inside the convex hull of the corpus coordinates (thesis §5.2).
    pub convex_hull: bool,
    /// PCA coordinates of the linear space.
    pub linear_dim: usize,
}

impl Default for NavigatorOptions {
    fn default() -> Self {
        NavigatorOptions {
            validity: ValidityOptions::default(),
            negative_tolerance: LOG_FLOOR,
            convex_hull: false,
            linear_dim: LINEAR_DIM,
        }
    }
}

/// The result of an edit.
#[derive(Debug, Clone)]
pub struct EditOutcome {
    /// New coordinates in the space.
    pub coords: Vec<f64>,
    /// Amount requested (trait units).
    pub requested: f64,
    /// Amount applied (`t · requested`).
    pub applied: f64,
    /// The check that stopped the move short of the request, if any.
    pub stopped_by: Option<Check>,
    /// The back-projected table (clamped at 0, always valid).
    pub table: brdf::MerlTable,
    /// Validity report of the table.
    pub report: ValidityReport,
    /// How many of the table's values were below zero before the clamp ([`State::clamped`]).
    pub clamped: usize,
}

/// A point of a space with its back-projection, as an editor session keeps it.
#[derive(Debug, Clone)]
pub struct State {
    /// Coordinates in the space.
    pub coords: Vec<f64>,
    /// PCA coefficients.
    pub pca: Vec<f64>,
    /// Log-space back-projection `m + U c`.
    pub log: Vec<f32>,
}

impl State {
    /// How many back-projected values `exp(y) − floor` are below zero (`y < ln floor`), i.e.
    /// clamped at 0 in the written table; each such deficit is less than the floor.
    pub fn clamped(&self) -> usize {
        let threshold = (LOG_FLOOR as f32).ln();
        self.log.iter().filter(|&&y| y < threshold).count()
    }
}

/// Moves through a space of a model, keeping every result valid: navigation in the linear
/// (PCA) and chart spaces (thesis §5.2), with trait sets and process paths (§5.4).
///
/// A [`Navigator`] holds a model, a space and the validity settings. [`Navigator::edit`] adds
/// `amount` units of a trait to a point: the move `x → x + t·Δ`, `Δ = amount · w/‖w‖²`, is
/// taken for the largest `t ∈ [0, 1]` at which the back-projected material is still valid, and
/// the outcome says which check stopped it. The back-projection of the PCA coefficients `c` is
/// `y = m + U c` in log space, BRDF `f = exp(y) − floor`; a value is negative exactly when
/// `y < ln(floor)`. The written table is `max(f, 0)`.
///
/// **Linear space.** `y(t) = y(0) + t·UΔ` is affine in `t`, so the non-negativity border is
/// found exactly in one pass, and the albedo (a positive sum of `max(exp(y) − floor, 0)`, a
/// convex function of `t`) is below the limit on an interval that bisection finds from the
/// few basis rows the albedo quadrature reads. **Chart space.** The back-projection (2.54) is
/// not linear: the segment is marched in [`CHART_MARCH_STEPS`] steps with the cheap checks
/// (hull, albedo) and the full non-negativity check, and the first failing step is bisected.
///
/// # Examples
///
/// ```
/// use traits::{fit_binary, FitOptions, Method, Navigator, NavigatorOptions, Space, TraitVector};
/// // Eight analytic materials, four matte and four glossy, and a 7-component model of them.
/// let mut corpus = reduce::Corpus::new(brdf::MATERIAL_DIM);
/// for i in 0..8 {
///     let spec = if i < 4 {
///         format!("lambert:kd={}", 0.1 + 0.1 * i as f64)
///     } else {
///         format!("ggx:alpha={},kd=0.2,ks=0.1", 0.5 - 0.1 * (i - 4) as f64)
///     };
///     let table = brdf::load(&spec).unwrap().tabulate();
///     corpus.push_values(format!("m{i}"), &table.values()).unwrap();
/// }
/// let model = reduce::build_model(&corpus, 7, None, None).unwrap();
/// let options = NavigatorOptions { linear_dim: 5, ..Default::default() };
/// let nav = Navigator::new(&model, Space::Linear, options).unwrap();
/// // A "glossy" trait fitted on the corpus coordinates.
/// let coords = nav.embedding.corpus().unwrap();
/// let labels: Vec<bool> = (0..8).map(|i| i >= 4).collect();
/// let glossy = TraitVector {
///     name: "glossy".into(),
///     direction: fit_binary(&coords, &labels, Method::Svm, &FitOptions::default()).unwrap(),
///     cross_validated: None,
///     variant: None,
/// };
/// // Make a matte material glossier; the move stops at the border of the valid set if needed.
/// let start = nav.embedding.of_name("m1").unwrap();
/// let out = nav.edit(&start, &glossy, 1.0).unwrap();
/// assert!(out.report.is_valid());
/// assert!(out.applied >= 0.0 && out.applied <= out.requested);
/// assert_eq!(out.stopped_by.is_some(), out.applied < out.requested);
/// // Trait units are calibrated: the score rises by exactly the amount applied.
/// let rise = glossy.direction.score(&out.coords) - glossy.direction.score(&start);
/// assert!((rise - out.applied).abs() < 1e-9);
/// ```
pub struct Navigator<'m> {
    /// The embedding.
    pub embedding: Embedding<'m>,
    /// Settings.
    pub options: NavigatorOptions,
    quadrature: AlbedoQuadrature,
    sparse: SparseRows,
    hull: Option<DMatrix<f64>>,
    row_norms: std::sync::OnceLock<Vec<f32>>,
}

impl<'m> Navigator<'m> {
    /// A navigator in `space` of `model`.
    pub fn new(model: &'m Model, space: Space, options: NavigatorOptions) -> Result<Navigator<'m>> {
        let embedding = Embedding::new(model, space, options.linear_dim)?;
        let quadrature = AlbedoQuadrature::from_options(&options.validity)?;
        let sparse = SparseRows::new(model, &quadrature, embedding.pca_dim);
        let hull = if options.convex_hull {
            Some(embedding.corpus()?)
        } else {
            None
        };
        Ok(Navigator {
            embedding,
            options,
            quadrature,
            sparse,
            hull,
            row_norms: Default::default(),
        })
    }

    /// The albedo quadrature used for every check.
    pub fn quadrature(&self) -> &AlbedoQuadrature {
        &self.quadrature
    }

    /// The state at coordinates `x` (one back-projection).
    pub fn state(&self, x: &[f64]) -> Result<State> {
        let pca = self.embedding.to_pca(x)?;
        let log = reconstruct_log(self.embedding.model, &pca)?;
        Ok(State {
            coords: x.to_vec(),
            pca,
            log,
        })
    }

    fn log_threshold(&self) -> f32 {
        // f = exp(y) − floor ≥ −tol  ⇔  y ≥ ln(floor − tol) (tol < floor), else always true.
        let t = LOG_FLOOR - self.options.negative_tolerance;
        if t > 0.0 {
            t.ln() as f32
        } else {
            f32::NEG_INFINITY
        }
    }

    fn albedo_ok(&self, c: &[f64]) -> bool {
        let a = self.sparse.albedo(c);
        let m = max_albedo(&a, &self.quadrature.theta_i_deg).0;
        m <= self.options.validity.albedo_limit
    }

    fn hull_ok(&self, x: &[f64]) -> Result<bool> {
        match &self.hull {
            None => Ok(true),
            Some(h) => Ok(hull_line_search(h, x, &vec![0.0; x.len()], 0.0)?.is_some()),
        }
    }

    fn nonneg_ok(&self, log: &[f32]) -> bool {
        let th = self.log_threshold();
        log.par_iter().all(|&v| v >= th)
    }

    /// Which checks a state fails (the navigation's own test: unclamped back-projection).
    pub fn failures(&self, s: &State) -> Result<Vec<Check>> {
        let mut f = Vec::new();
        if !self.nonneg_ok(&s.log) {
            f.push(Check::NonNegativity);
        }
        // The albedo of exactly the values that will be written (from the log vector).
        let a = self
            .quadrature
            .albedo_by(|c, b| reduce::from_log(s.log[c * BINS + b]).max(0.0));
        if max_albedo(&a, &self.quadrature.theta_i_deg).0 > self.options.validity.albedo_limit {
            f.push(Check::EnergyConservation);
        }
        if !self.hull_ok(&s.coords)? {
            f.push(Check::ConvexHull);
        }
        Ok(f)
    }

    /// The clamped table of a state and its full validity report.
    pub fn table(&self, s: &State) -> Result<(brdf::MerlTable, ValidityReport)> {
        let values: Vec<f64> = s
            .log
            .par_iter()
            .map(|&y| reduce::from_log(y).max(0.0))
            .collect();
        let table = brdf::MerlTable::from_values(values)?;
        let hull = if self.hull.is_some() {
            Some(self.hull_ok(&s.coords)?)
        } else {
            None
        };
        let report = validate(&table, &self.quadrature, &self.options.validity, hull);
        Ok((table, report))
    }

    /// An [`TraitsError::InvalidStart`] error naming the checks `start` fails, if any.
    fn check_start(&self, start: &State) -> Result<()> {
        let fails = self.failures(start)?;
        if fails.is_empty() {
            return Ok(());
        }
        Err(TraitsError::InvalidStart(
            fails
                .iter()
                .map(|c| c.to_string())
                .collect::<Vec<_>>()
                .join(", "),
        ))
    }

    /// Moves from `start` by `delta` (space coordinates) as far as `t ∈ [0, 1]` stays valid.
    /// Returns the new state, `t`, and the check that stopped the move (if `t < 1`).
    pub fn step(&self, start: &State, delta: &[f64]) -> Result<(State, f64, Option<Check>)> {
        self.check_start(start)?;
        if delta.len() != start.coords.len() {
            return Err(TraitsError::Dimension {
                what: "edit direction",
                expected: start.coords.len(),
                got: delta.len(),
            });
        }
        let at = |t: f64| -> Vec<f64> {
            start
                .coords
                .iter()
                .zip(delta)
                .map(|(a, d)| a + t * d)
                .collect()
        };
        match self.embedding.space {
            Space::Linear => self.step_linear(start, delta, &at),
            Space::Chart => self.step_chart(start, &at),
        }
    }

    fn step_linear(
        &self,
        start: &State,
        delta: &[f64],
        at: &dyn Fn(f64) -> Vec<f64>,
    ) -> Result<(State, f64, Option<Check>)> {
        let model = self.embedding.model;
        // dy = U Δ.
        let with_mean = reconstruct_log(model, delta)?;
        let dy: Vec<f32> = with_mean
            .par_iter()
            .zip(&model.pca.mean)
            .map(|(a, m)| a - m)
            .collect();
        let mut buf = Vec::new();
        let (t, why) = self.line_linear(start, delta, &dy, 1.0, &mut buf)?;
        Ok(self.state_on_line(start, at, t, why, buf))
    }

    fn state_on_line(
        &self,
        start: &State,
        at: &dyn Fn(f64) -> Vec<f64>,
        t: f64,
        why: Option<Check>,
        buf: Vec<f32>,
    ) -> (State, f64, Option<Check>) {
        if t == 0.0 {
            return (start.clone(), 0.0, why);
        }
        let x = at(t);
        (
            State {
                coords: x.clone(),
                pca: x,
                log: buf,
            },
            t,
            why,
        )
    }

    /// One fused pass: `out = y0 + ts·dy` in f32 (the values that will be written), whether
    /// all of them pass non-negativity, and the exact non-negativity border `t` of the line
    /// `y0 + t·scale·dy`.
    fn write_line(
        &self,
        y0: &[f32],
        dy: &[f32],
        ts: f32,
        scale: f32,
        out: &mut Vec<f32>,
    ) -> (bool, f64) {
        let th = self.log_threshold();
        out.resize(y0.len(), 0.0);
        const BLOCK: usize = 1 << 15;
        out.par_chunks_mut(BLOCK)
            .zip(y0.par_chunks(BLOCK))
            .zip(dy.par_chunks(BLOCK))
            .map(|((o, y), d)| {
                let mut ok = true;
                let mut tn = f32::INFINITY;
                for ((o, &y), &d) in o.iter_mut().zip(y).zip(d) {
                    let v = y + ts * d;
                    *o = v;
                    ok &= v >= th;
                    let ds = d * scale;
                    if ds < 0.0 {
                        tn = tn.min((th - y) / ds);
                    }
                }
                (ok, tn as f64)
            })
            .reduce(|| (true, f64::INFINITY), |a, b| (a.0 && b.0, a.1.min(b.1)))
    }

    /// Whether the albedo of exactly the f32 log values `log` is within the limit.
    fn log_albedo_ok(&self, log: &[f32]) -> bool {
        let a = self
            .quadrature
            .albedo_by(|c, b| reduce::from_log(log[c * BINS + b]).max(0.0));
        max_albedo(&a, &self.quadrature.theta_i_deg).0 <= self.options.validity.albedo_limit
    }

    /// The linear-space line search with `y(t) = y(0) + t·scale·dy`. Writes the log vector of
    /// the accepted point into `buf` (valid when the returned `t > 0`) and returns `t` and the
    /// check that stopped the move.
    fn line_linear(
        &self,
        start: &State,
        delta: &[f64],
        dy: &[f32],
        scale: f32,
        buf: &mut Vec<f32>,
    ) -> Result<(f64, Option<Check>)> {
        let limit = self.options.validity.albedo_limit;
        let line = self.sparse.line(&start.log, dy, scale);
        let end: Vec<f64> = start.coords.iter().zip(delta).map(|(a, d)| a + d).collect();
        let albedo_end_ok = line.max_albedo(1.0) <= limit;
        let hull_end_ok = self.hull_ok(&end)?;
        // Optimistic pass: the whole move, its exact f32 values checked while written.
        let (all_ok, t_nonneg) = self.write_line(&start.log, dy, scale, scale, buf);
        if all_ok && albedo_end_ok && hull_end_ok && self.log_albedo_ok(buf) {
            return Ok((1.0, None));
        }
        let mut limits = vec![(t_nonneg, Check::NonNegativity)];
        if !albedo_end_ok {
            // Albedo: convex in t, valid at 0: bisection on [0, 1].
            let (mut lo, mut hi) = (0.0f64, 1.0f64);
            for _ in 0..BISECTION_STEPS {
                let mid = 0.5 * (lo + hi);
                if line.max_albedo(mid as f32) <= limit {
                    lo = mid;
                } else {
                    hi = mid;
                }
            }
            limits.push((lo, Check::EnergyConservation));
        }
        if let Some(h) = &self.hull {
            let t = hull_line_search(h, &start.coords, delta, 1.0)?.unwrap_or(0.0);
            limits.push((t, Check::ConvexHull));
        }
        let (mut t, mut why) = (1.0, None);
        for (lt, c) in limits {
            if lt < t {
                t = lt.max(0.0);
                why = Some(c);
            }
        }
        // Rounding guard: the border was found in f64/f32 arithmetic on the line; the written
        // values are f32. Back off by 10⁻⁶, 4·10⁻⁶, … of t until they pass.
        let t_border = t;
        for k in 0..11 {
            if k > 0 {
                t = t_border * (1.0 - 1e-6 * 4f64.powi(k - 1));
            }
            if t <= 0.0 {
                break;
            }
            let ts = t as f32 * scale;
            let (ok, _) = self.write_line(&start.log, dy, ts, scale, buf);
            let x: Vec<f64> = start
                .coords
                .iter()
                .zip(delta)
                .map(|(a, d)| a + t * d)
                .collect();
            if ok && self.log_albedo_ok(buf) && self.hull_ok(&x)? {
                return Ok((t, why));
            }
            why = why.or(Some(Check::NonNegativity));
        }
        Ok((0.0, why))
    }

    fn step_chart(
        &self,
        start: &State,
        at: &dyn Fn(f64) -> Vec<f64>,
    ) -> Result<(State, f64, Option<Check>)> {
        // Cheap checks first; non-negativity screened against the start's back-projection.
        let eval = |t: f64| -> Result<(Vec<f64>, Vec<f64>, Vec<Check>)> {
            let x = at(t);
            let pca = self.embedding.to_pca(&x)?;
            let mut f = Vec::new();
            if !self.hull_ok(&x)? {
                f.push(Check::ConvexHull);
            }
            if !self.albedo_ok(&pca) {
                f.push(Check::EnergyConservation);
            }
            if f.is_empty() && !self.nonneg_near(start, &pca)? {
                f.push(Check::NonNegativity);
            }
            Ok((x, pca, f))
        };
        let mut last: (f64, Vec<f64>, Vec<f64>) = (0.0, start.coords.clone(), start.pca.clone());
        let mut why = None;
        for i in 1..=CHART_MARCH_STEPS {
            let t = i as f64 / CHART_MARCH_STEPS as f64;
            let (x, pca, f) = eval(t)?;
            if f.is_empty() {
                last = (t, x, pca);
                continue;
            }
            // Bisect between the last valid step and this one.
            let (mut lo, mut hi) = (last.0, t);
            why = Some(f[0]);
            for _ in 0..BISECTION_STEPS / 2 {
                let mid = 0.5 * (lo + hi);
                let (x, pca, f) = eval(mid)?;
                if f.is_empty() {
                    lo = mid;
                    last = (mid, x, pca);
                } else {
                    hi = mid;
                    why = Some(f[0]);
                }
            }
            break;
        }
        if last.0 == 0.0 {
            return Ok((start.clone(), 0.0, why));
        }
        // The written values: one full back-projection, checked exactly; back off a little
        // if f32 rounding puts it over a border.
        let t_border = last.0;
        for k in 0..8 {
            let (t, x, pca) = if k == 0 {
                (last.0, last.1.clone(), last.2.clone())
            } else {
                let t = t_border * (1.0 - 1e-4 * 4f64.powi(k - 1));
                let x = at(t);
                let pca = self.embedding.to_pca(&x)?;
                (t, x, pca)
            };
            let log = reconstruct_log(self.embedding.model, &pca)?;
            let s = State {
                coords: x,
                pca,
                log,
            };
            if self.failures(&s)?.is_empty() {
                return Ok((s, t, why));
            }
            why = why.or(Some(Check::NonNegativity));
        }
        Ok((start.clone(), 0.0, why))
    }

    /// Norms of the basis rows over the space's PCA coordinates (computed on first use).
    fn row_norms(&self) -> &[f32] {
        self.row_norms.get_or_init(|| {
            let p = &self.embedding.model.pca;
            let (kk, k) = (p.components, self.embedding.pca_dim);
            (0..p.mean.len())
                .into_par_iter()
                .map(|j| {
                    p.basis[j * kk..j * kk + k]
                        .iter()
                        .map(|v| v * v)
                        .sum::<f32>()
                        .sqrt()
                })
                .collect()
        })
    }

    /// Non-negativity of the back-projection of `pca`, from a valid `base` state: a value can
    /// only have crossed the threshold where `y_base − ‖U_j‖·‖c − c_base‖` is below it (Cauchy–
    /// Schwarz), and only those rows are evaluated exactly. Falls back to a full
    /// back-projection when too many rows are near the threshold.
    fn nonneg_near(&self, base: &State, pca: &[f64]) -> Result<bool> {
        let th = self.log_threshold();
        if th == f32::NEG_INFINITY {
            return Ok(true);
        }
        if base.pca.len() != pca.len() || base.log.is_empty() {
            let log = reconstruct_log(self.embedding.model, pca)?;
            return Ok(self.nonneg_ok(&log));
        }
        let dist = pca
            .iter()
            .zip(&base.pca)
            .map(|(a, b)| (a - b).powi(2))
            .sum::<f64>()
            .sqrt();
        // Margin for the f32 rounding of the base and of the bound.
        let reach = (dist * (1.0 + 1e-4)) as f32;
        let norms = self.row_norms();
        let near: Vec<usize> = base
            .log
            .par_iter()
            .zip(norms)
            .enumerate()
            .filter(|(_, (&y, &r))| y - r * reach - 1e-4 < th)
            .map(|(j, _)| j)
            .collect();
        tracing::debug!(near = near.len(), dist, "non-negativity screen");
        if near.len() > base.log.len() / 3 {
            let log = reconstruct_log(self.embedding.model, pca)?;
            return Ok(self.nonneg_ok(&log));
        }
        let p = &self.embedding.model.pca;
        let kk = p.components;
        let th = th as f64;
        Ok(near.par_iter().all(|&j| {
            let row = &p.basis[j * kk..j * kk + pca.len()];
            let y = p.mean[j] as f64
                + row
                    .iter()
                    .zip(pca)
                    .map(|(&u, &c)| u as f64 * c)
                    .sum::<f64>();
            y >= th
        }))
    }

    /// Adds `amount` units of `trait_vector` to the point `coords` (thesis §5: adding or
    /// subtracting a scaled trait vector), stopping at the border of the valid set.
    pub fn edit(
        &self,
        coords: &[f64],
        trait_vector: &TraitVector,
        amount: f64,
    ) -> Result<EditOutcome> {
        self.edit_many(coords, &[(trait_vector, amount)])
    }

    /// Adds several scaled traits at once (one straight move).
    pub fn edit_many(&self, coords: &[f64], edits: &[(&TraitVector, f64)]) -> Result<EditOutcome> {
        if !edits.iter().all(|(_, a)| a.is_finite()) {
            return Err(TraitsError::InvalidParameter("non-finite amount".into()));
        }
        let mut delta = vec![0.0; coords.len()];
        for (tv, a) in edits {
            let u = tv.direction.unit_step();
            if u.len() != coords.len() {
                return Err(TraitsError::Dimension {
                    what: "trait direction",
                    expected: coords.len(),
                    got: u.len(),
                });
            }
            for (d, v) in delta.iter_mut().zip(u) {
                *d += a * v;
            }
        }
        let requested = edits.iter().map(|(_, a)| a).sum::<f64>();
        let (s, t, why) = match self.embedding.space {
            Space::Linear => {
                // The start and the move back-projected in one pass over the basis.
                let pca = self.embedding.to_pca(coords)?;
                let (log, dy) = reconstruct_log_pair(self.embedding.model, &pca, &delta)?;
                let start = State {
                    coords: coords.to_vec(),
                    pca,
                    log,
                };
                self.check_start(&start)?;
                let mut buf = Vec::new();
                let (t, why) = self.line_linear(&start, &delta, &dy, 1.0, &mut buf)?;
                let at = |t: f64| -> Vec<f64> {
                    coords.iter().zip(&delta).map(|(a, d)| a + t * d).collect()
                };
                self.state_on_line(&start, &at, t, why, buf)
            }
            Space::Chart => {
                let start = self.state(coords)?;
                self.step(&start, &delta)?
            }
        };
        let (table, report) = self.table(&s)?;
        if !report.is_valid() {
            return Err(TraitsError::Numerical(format!(
                "edited table failed {:?} after the border search",
                report.failed
            )));
        }
        Ok(EditOutcome {
            clamped: s.clamped(),
            coords: s.coords,
            requested,
            applied: t * requested,
            stopped_by: why,
            table,
            report,
        })
    }
}

/// An editing session: a current point whose back-projection is kept, and the
/// back-projections `U·(w/‖w‖²)` of the traits used so far, so that in the linear space a
/// slider move costs a few passes over the table instead of a matrix product with the basis.
///
/// # Examples
///
/// ```
/// use traits::{fit_binary, FitOptions, Method, Navigator, NavigatorOptions, Session};
/// use traits::{Space, SpherePreview, TraitVector};
/// // Eight analytic materials, four matte and four glossy, and a 7-component model of them.
/// let mut corpus = reduce::Corpus::new(brdf::MATERIAL_DIM);
/// for i in 0..8 {
///     let spec = if i < 4 {
///         format!("lambert:kd={}", 0.1 + 0.1 * i as f64)
///     } else {
///         format!("ggx:alpha={},kd=0.2,ks=0.1", 0.5 - 0.1 * (i - 4) as f64)
///     };
///     let table = brdf::load(&spec).unwrap().tabulate();
///     corpus.push_values(format!("m{i}"), &table.values()).unwrap();
/// }
/// let model = reduce::build_model(&corpus, 7, None, None).unwrap();
/// let options = NavigatorOptions { linear_dim: 5, ..Default::default() };
/// let nav = Navigator::new(&model, Space::Linear, options).unwrap();
/// // A "glossy" trait fitted on the corpus coordinates.
/// let coords = nav.embedding.corpus().unwrap();
/// let labels: Vec<bool> = (0..8).map(|i| i >= 4).collect();
/// let glossy = TraitVector {
///     name: "glossy".into(),
///     direction: fit_binary(&coords, &labels, Method::Svm, &FitOptions::default()).unwrap(),
///     cross_validated: None,
///     variant: None,
/// };
/// let start = nav.embedding.of_name("m5").unwrap();
/// let mut session = Session::new(&nav, &start).unwrap();
/// let preview = SpherePreview::new(32, [0.3, 0.3, 1.0]);
/// let before = session.preview(&preview);
/// // Two slider moves, each kept only as far as the material stays valid.
/// for amount in [0.3, -0.6] {
///     let (applied, stopped_by) = session.nudge(&glossy, amount).unwrap();
///     assert!(applied.abs() <= amount.abs() + 1e-12);
///     assert_eq!(stopped_by.is_some(), applied != amount);
/// }
/// let after = session.preview(&preview);
/// assert_eq!(after.len(), 32 * 32);
/// assert!(after.iter().flatten().all(|v| *v >= 0.0));
/// assert_ne!(before, after);
/// // The session's table is the one the navigator writes for the same point.
/// let (table, report) = session.table().unwrap();
/// assert!(report.is_valid());
/// let (again, _) = nav.table(&nav.state(&session.state().coords).unwrap()).unwrap();
/// let (a, b) = (table.values(), again.values());
/// assert!(a.iter().zip(&b).all(|(x, y)| (x - y).abs() <= 1e-4 * y.abs().max(1.0)));
/// ```
pub struct Session<'a, 'm> {
    nav: &'a Navigator<'m>,
    state: State,
    unit_dirs: std::collections::HashMap<String, Vec<f32>>,
    scratch: Vec<f32>,
}

impl<'a, 'm> Session<'a, 'm> {
    /// Starts at `coords`, which must be valid.
    pub fn new(nav: &'a Navigator<'m>, coords: &[f64]) -> Result<Session<'a, 'm>> {
        let state = nav.state(coords)?;
        let f = nav.failures(&state)?;
        if !f.is_empty() {
            return Err(TraitsError::InvalidStart(format!("{f:?}")));
        }
        Ok(Session {
            nav,
            state,
            unit_dirs: Default::default(),
            scratch: Vec::new(),
        })
    }

    /// Returns to `coords`, a point a session already held (undo, redo), without checking it
    /// again.
    ///
    /// A point reached by a move stopped at a border sits on that border; its back-projection
    /// was accumulated along the moves, and computing it afresh from `coords` can put it on the
    /// wrong side by rounding, so [`Session::new`] could refuse a point the user had a moment
    /// ago. Only the dimension is checked here.
    pub fn resume(nav: &'a Navigator<'m>, coords: &[f64]) -> Result<Session<'a, 'm>> {
        Ok(Session {
            nav,
            state: nav.state(coords)?,
            unit_dirs: Default::default(),
            scratch: Vec::new(),
        })
    }

    /// The current point.
    pub fn state(&self) -> &State {
        &self.state
    }

    /// Adds `amount` units of a trait to the current point as far as it stays valid; returns
    /// the amount applied and the check that stopped the move.
    ///
    /// In the linear space this is one fused pass over the table (the move, its exact f32
    /// values and their non-negativity) plus the albedo at the quadrature's bins; a second
    /// pass is needed only when the move stops at a border.
    pub fn nudge(&mut self, tv: &TraitVector, amount: f64) -> Result<(f64, Option<Check>)> {
        if !amount.is_finite() {
            return Err(TraitsError::InvalidParameter("non-finite amount".into()));
        }
        let unit = tv.direction.unit_step();
        if unit.len() != self.state.coords.len() {
            return Err(TraitsError::Dimension {
                what: "trait direction",
                expected: self.state.coords.len(),
                got: unit.len(),
            });
        }
        let delta: Vec<f64> = unit.iter().map(|u| u * amount).collect();
        match self.nav.embedding.space {
            Space::Linear => {
                if !self.unit_dirs.contains_key(&tv.name) {
                    let model = self.nav.embedding.model;
                    let with_mean = reconstruct_log(model, &unit)?;
                    let dy: Vec<f32> = with_mean
                        .par_iter()
                        .zip(&model.pca.mean)
                        .map(|(a, m)| a - m)
                        .collect();
                    self.unit_dirs.insert(tv.name.clone(), dy);
                }
                let dy = &self.unit_dirs[&tv.name];
                let (t, why) = self.nav.line_linear(
                    &self.state,
                    &delta,
                    dy,
                    amount as f32,
                    &mut self.scratch,
                )?;
                if t > 0.0 {
                    for (x, d) in self.state.coords.iter_mut().zip(&delta) {
                        *x += t * d;
                    }
                    self.state.pca.clone_from(&self.state.coords);
                    std::mem::swap(&mut self.state.log, &mut self.scratch);
                }
                Ok((t * amount, why))
            }
            Space::Chart => {
                let (s, t, why) = self.nav.step(&self.state, &delta)?;
                self.state = s;
                Ok((t * amount, why))
            }
        }
    }

    /// The lit-sphere preview of the current point: RGB radiance per pixel, read from the
    /// kept back-projection at the preview's bins only.
    pub fn preview(&self, p: &crate::preview::SpherePreview) -> Vec<[f32; 3]> {
        p.shade_log(&self.state.log)
    }

    /// The current table (clamped at 0) and its full validity report.
    pub fn table(&self) -> Result<(brdf::MerlTable, ValidityReport)> {
        self.nav.table(&self.state)
    }
}

/// How a path through several materials is parameterised (thesis §5.4).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum PathKind {
    /// Straight segments between consecutive materials.
    Piecewise,
    /// The least-squares line through the materials, from the projection of the first to the
    /// projection of the last.
    LeastSquares,
}

/// `steps` points (≥ 2) along a path through `points` (each in space coordinates), evenly
/// spaced in arc length for the piecewise path.
pub fn path_points(points: &[Vec<f64>], steps: usize, kind: PathKind) -> Result<Vec<Vec<f64>>> {
    if points.len() < 2 || steps < 2 {
        return Err(TraitsError::InvalidParameter(
            "a path needs at least two materials and two steps".into(),
        ));
    }
    let d = points[0].len();
    if points.iter().any(|p| p.len() != d) {
        return Err(TraitsError::Dimension {
            what: "path point",
            expected: d,
            got: points
                .iter()
                .map(|p| p.len())
                .find(|&l| l != d)
                .unwrap_or(d),
        });
    }
    let lerp = |a: &[f64], b: &[f64], t: f64| -> Vec<f64> {
        a.iter().zip(b).map(|(x, y)| x + t * (y - x)).collect()
    };
    match kind {
        PathKind::Piecewise => {
            let seg: Vec<f64> = points
                .windows(2)
                .map(|w| {
                    w[0].iter()
                        .zip(&w[1])
                        .map(|(a, b)| (a - b).powi(2))
                        .sum::<f64>()
                        .sqrt()
                })
                .collect();
            let total: f64 = seg.iter().sum();
            Ok((0..steps)
                .map(|i| {
                    let mut s = total * i as f64 / (steps - 1) as f64;
                    for (j, &l) in seg.iter().enumerate() {
                        if s <= l || j == seg.len() - 1 {
                            let t = if l > 0.0 { (s / l).min(1.0) } else { 0.0 };
                            return lerp(&points[j], &points[j + 1], t);
                        }
                        s -= l;
                    }
                    points[points.len() - 1].clone()
                })
                .collect())
        }
        PathKind::LeastSquares => {
            let n = points.len();
            let m = DMatrix::from_fn(n, d, |i, k| points[i][k]);
            let mean = m.row_mean();
            let centred = DMatrix::from_fn(n, d, |i, k| m[(i, k)] - mean[k]);
            let svd = centred.svd(false, true);
            let vt = svd
                .v_t
                .ok_or_else(|| TraitsError::Numerical("SVD".into()))?;
            let (imax, _) = svd.singular_values.iter().enumerate().fold(
                (0, f64::NEG_INFINITY),
                |b, (i, &s)| if s > b.1 { (i, s) } else { b },
            );
            let dir: Vec<f64> = vt.row(imax).iter().copied().collect();
            let proj = |p: &[f64]| -> Vec<f64> {
                let s: f64 = p
                    .iter()
                    .zip(mean.iter())
                    .zip(&dir)
                    .map(|((a, m), u)| (a - m) * u)
                    .sum();
                mean.iter().zip(&dir).map(|(m, u)| m + s * u).collect()
            };
            let (a, b) = (proj(&points[0]), proj(&points[n - 1]));
            Ok((0..steps)
                .map(|i| lerp(&a, &b, i as f64 / (steps - 1) as f64))
                .collect())
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn piecewise_path_passes_through_the_materials() {
        let pts = vec![vec![0.0, 0.0], vec![1.0, 0.0], vec![1.0, 3.0]];
        let p = path_points(&pts, 5, PathKind::Piecewise).unwrap();
        assert_eq!(p[0], pts[0]);
        assert_eq!(p[4], pts[2]);
        // Arc length 4 in 4 steps: the second point is the corner.
        assert!((p[1][0] - 1.0).abs() < 1e-12 && p[1][1].abs() < 1e-12);
        let l = path_points(&pts, 3, PathKind::LeastSquares).unwrap();
        // The line's points are collinear.
        let (a, b, c) = (&l[0], &l[1], &l[2]);
        let cross = (b[0] - a[0]) * (c[1] - a[1]) - (b[1] - a[1]) * (c[0] - a[0]);
        assert!(cross.abs() < 1e-9);
        assert!(path_points(&pts[..1], 3, PathKind::Piecewise).is_err());
    }
}
