//! The training corpus: many materials tabulated on one sample grid.

use crate::error::{Result, SamplingError};
use crate::grid::{GridTable, SampleGrid};

use brdf::Source;

pub use brdf::{from_log_clamped, to_log, LOG_FLOOR};

/// The training corpus: materials tabulated on one [`SampleGrid`], as rows of one matrix. Row
/// `m` holds the `3 × grid.len()` channel-major values of material `m` (1/sr, missing values
/// stored as 0).
///
/// The log transform is the workspace's one definition, [`brdf::LogTransform`]: [`to_log`] is
/// `ln(max(f, 0) + LOG_FLOOR)` and [`from_log_clamped`] its inverse clamped at 0 (a
/// reconstruction never reports negative BRDF values).
///
/// Values are stored as `f32`: on the full MERL grid the 96-material corpus takes 1.7 GB
/// (twice that as `f64`). Every computation on them accumulates in `f64`.
///
/// # Examples
///
/// ```
/// use sampling::{SampleGrid, TrainingSet};
///
/// let grid = SampleGrid::new(9, 9, 18).unwrap();
/// let set = TrainingSet::from_inputs(&["lambert:kd=0.2", "ggx:alpha=0.3"], grid).unwrap();
/// assert_eq!(set.len(), 2);
/// assert_eq!(set.dim(), 3 * grid.len());
/// ```
#[derive(Debug, Clone)]
pub struct TrainingSet {
    /// The grid every material is tabulated on.
    pub grid: SampleGrid,
    /// Material names.
    pub names: Vec<String>,
    /// `names.len() × dim()` values, material-major.
    pub values: Vec<f32>,
}

impl TrainingSet {
    /// Builds from tables on one grid. Negative (missing) values become 0; non-finite values are
    /// an error.
    pub fn from_tables(names: Vec<String>, tables: &[GridTable]) -> Result<Self> {
        let grid = match tables.first() {
            Some(t) => t.grid,
            None => return Err(SamplingError::InvalidParameter("no training tables".into())),
        };
        if names.len() != tables.len() {
            return Err(SamplingError::Dimension(format!(
                "{} names for {} tables",
                names.len(),
                tables.len()
            )));
        }
        let mut values = Vec::with_capacity(tables.len() * 3 * grid.len());
        for (name, t) in names.iter().zip(tables) {
            if t.grid != grid {
                return Err(SamplingError::Dimension(format!(
                    "material {name} is on a different grid"
                )));
            }
            if t.values.iter().any(|v| !v.is_finite()) {
                return Err(SamplingError::NonFinite(format!("material {name}")));
            }
            values.extend(t.values.iter().map(|v| v.max(0.0) as f32));
        }
        Ok(TrainingSet {
            grid,
            names,
            values,
        })
    }

    /// An empty set on `grid`, to be filled with [`TrainingSet::push`].
    pub fn empty(grid: SampleGrid) -> Self {
        TrainingSet {
            grid,
            names: Vec::new(),
            values: Vec::new(),
        }
    }

    /// Appends one material given as `3 × grid.len()` channel-major `f32` values. Negative
    /// (missing) values become 0; non-finite values or a wrong length are an error.
    pub fn push(&mut self, name: String, values: &[f32]) -> Result<()> {
        if values.len() != self.dim() {
            return Err(SamplingError::Dimension(format!(
                "material {name}: {} values, the grid needs {}",
                values.len(),
                self.dim()
            )));
        }
        if values.iter().any(|v| !v.is_finite()) {
            return Err(SamplingError::NonFinite(format!("material {name}")));
        }
        self.values.extend(values.iter().map(|v| v.max(0.0)));
        self.names.push(name);
        Ok(())
    }

    /// Decodes every neural-BRDF material of `dir` (e.g. `<data>/nbrdf/merl`) on `grid`, one
    /// material at a time (on the full grid through the fast `f32` tabulation).
    pub fn from_nbrdf_dir(dir: impl AsRef<std::path::Path>, grid: SampleGrid) -> Result<Self> {
        let dir = dir.as_ref();
        let sources: Vec<Source> = brdf::nbrdf::list(dir)?
            .into_iter()
            .map(|name| Source::Nbrdf {
                dir: dir.to_path_buf(),
                name,
            })
            .collect();
        Self::from_sources(&sources, grid)
    }

    /// Tabulates a corpus given as in [`brdf::sources`] (NBRDF directories, `.binary`
    /// files, material specs) on `grid`.
    pub fn from_inputs<P: AsRef<std::path::Path>>(inputs: &[P], grid: SampleGrid) -> Result<Self> {
        Self::from_sources(&brdf::sources(inputs)?, grid)
    }

    /// Tabulates corpus sources on `grid`, one material at a time (neural BRDFs through
    /// [`tabulate_nbrdf_f32`]).
    pub fn from_sources(sources: &[Source], grid: SampleGrid) -> Result<Self> {
        let mut set = TrainingSet::empty(grid);
        set.values.reserve_exact(sources.len() * set.dim());
        for source in sources {
            let values = match source {
                Source::Nbrdf { dir, name } => {
                    tabulate_nbrdf_f32(&brdf::nbrdf::Nbrdf::load(dir, name)?, grid)
                }
                other if grid == SampleGrid::FULL => other.values_f32()?,
                other => GridTable::tabulate(&other.load()?, grid)
                    .values
                    .iter()
                    .map(|&v| v as f32)
                    .collect(),
            };
            set.push(source.name(), &values)?;
        }
        if set.is_empty() {
            return Err(SamplingError::InvalidParameter("no training tables".into()));
        }
        Ok(set)
    }

    /// Tabulates arbitrary BRDFs (e.g. from `brdf::load`) on `grid`.
    pub fn from_brdfs(brdfs: &[Box<dyn brdf::Brdf>], grid: SampleGrid) -> Result<Self> {
        let tables: Vec<GridTable> = brdfs
            .iter()
            .map(|b| GridTable::tabulate(b.as_ref(), grid))
            .collect();
        let names = brdfs.iter().map(|b| b.name()).collect();
        Self::from_tables(names, &tables)
    }

    /// Number of materials.
    pub fn len(&self) -> usize {
        self.names.len()
    }

    /// Whether there are no materials.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// Values per material (`3 × grid.len()`).
    pub fn dim(&self) -> usize {
        3 * self.grid.len()
    }

    /// The values of material `m`.
    pub fn material(&self, m: usize) -> &[f32] {
        let d = self.dim();
        &self.values[m * d..(m + 1) * d]
    }
}

/// A neural BRDF on `grid` as `3 × grid.len()` channel-major `f32` values: the fast MERL-grid
/// tabulation on the full grid, direct evaluation at the grid angles otherwise.
pub fn tabulate_nbrdf_f32(nbrdf: &brdf::nbrdf::Nbrdf, grid: SampleGrid) -> Vec<f32> {
    if grid == SampleGrid::FULL {
        nbrdf.tabulate_f32()
    } else {
        GridTable::from_nbrdf(nbrdf, grid)
            .values
            .iter()
            .map(|&v| v as f32)
            .collect()
    }
}

/// Row index (`channel × grid.len() + point`) of a (grid point, channel) pair.
#[inline]
pub fn row_of(grid: &SampleGrid, point: usize, channel: usize) -> usize {
    channel * grid.len() + point
}

/// (grid point, channel) of a row index.
#[inline]
pub fn point_of(grid: &SampleGrid, row: usize) -> (usize, usize) {
    (row % grid.len(), row / grid.len())
}

/// Whether a planar-sample gonioreflectometer can measure a grid point: both directions of
/// the configuration (with φh = 0) above the horizon.
pub fn measurable(grid: &SampleGrid, point: usize) -> bool {
    let (th, td, pd) = grid.angles(point);
    brdf::HalfDiff::isotropic(th, td, pd).above_horizon()
}

/// Measurable mask of all rows (`3 × grid.len()`).
pub fn measurable_rows(grid: &SampleGrid) -> Vec<bool> {
    let pts: Vec<bool> = (0..grid.len()).map(|p| measurable(grid, p)).collect();
    (0..3 * grid.len()).map(|r| pts[r % grid.len()]).collect()
}
