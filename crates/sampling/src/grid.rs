//! Regular sub-grids of the MERL grid and tables on them.

use brdf::{bin_angles, bin_index, grid_coordinates, PHI_D_RES, THETA_D_RES, THETA_H_RES};
use brdf::{Brdf, HalfDiff, MerlTable, Rgb};
use rayon::prelude::*;

use crate::error::{Result, SamplingError};

/// Every `step`-th index of the MERL grid along each axis: the grid a training corpus is
/// tabulated on and a reconstruction lives on.
///
/// Stride 1 is the full 90 × 90 × 180 MERL grid, on which the results of `docs/sampling.md`
/// are measured; sub-grids train in seconds and serve the tests and examples.
///
/// # Examples
///
/// ```
/// use sampling::SampleGrid;
///
/// let grid = SampleGrid::new(9, 9, 18).unwrap();
/// assert_eq!(grid.shape(), (10, 10, 10));
/// assert_eq!(grid.len(), 1000);
/// assert_eq!(SampleGrid::FULL.len(), brdf::BINS);
/// // a grid point and its flat index round-trip
/// let idx = grid.index(3, 4, 5);
/// assert_eq!(grid.coords(idx), (3, 4, 5));
/// ```
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct SampleGrid {
    /// Stride along θh.
    pub theta_h_step: usize,
    /// Stride along θd.
    pub theta_d_step: usize,
    /// Stride along φd.
    pub phi_d_step: usize,
}

/// Parses `full` (90 × 90 × 180), `quarter` (strides 2), one stride `S` or strides `A:B:C`.
///
/// ```
/// use sampling::SampleGrid;
/// assert_eq!("full".parse::<SampleGrid>().unwrap(), SampleGrid::FULL);
/// assert_eq!("2:2:4".parse::<SampleGrid>().unwrap(), SampleGrid::new(2, 2, 4).unwrap());
/// assert!("0".parse::<SampleGrid>().is_err());
/// ```
impl std::str::FromStr for SampleGrid {
    type Err = SamplingError;

    fn from_str(s: &str) -> Result<Self> {
        let bad = || {
            SamplingError::InvalidParameter(format!(
                "grid {s:?}: expected full, quarter, S or A:B:C"
            ))
        };
        let steps: Vec<usize> = match s {
            "full" => vec![1, 1, 1],
            "quarter" => vec![2, 2, 2],
            other => other
                .split(':')
                .map(|x| x.trim().parse::<usize>().map_err(|_| bad()))
                .collect::<Result<_>>()?,
        };
        match steps[..] {
            [s] => SampleGrid::new(s, s, s),
            [a, b, c] => SampleGrid::new(a, b, c),
            _ => Err(bad()),
        }
    }
}

impl SampleGrid {
    /// The full MERL grid.
    pub const FULL: SampleGrid = SampleGrid {
        theta_h_step: 1,
        theta_d_step: 1,
        phi_d_step: 1,
    };

    /// A grid with the given strides (each ≥ 1).
    pub fn new(theta_h_step: usize, theta_d_step: usize, phi_d_step: usize) -> Result<Self> {
        if theta_h_step == 0 || theta_d_step == 0 || phi_d_step == 0 {
            return Err(SamplingError::InvalidParameter(
                "grid strides must be at least 1".into(),
            ));
        }
        Ok(SampleGrid {
            theta_h_step,
            theta_d_step,
            phi_d_step,
        })
    }

    /// Number of points along (θh, θd, φd).
    pub fn shape(&self) -> (usize, usize, usize) {
        (
            THETA_H_RES.div_ceil(self.theta_h_step),
            THETA_D_RES.div_ceil(self.theta_d_step),
            PHI_D_RES.div_ceil(self.phi_d_step),
        )
    }

    /// Number of grid points (per channel).
    pub fn len(&self) -> usize {
        let (a, b, c) = self.shape();
        a * b * c
    }

    /// Whether the grid is empty (never, for valid strides).
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// Flat index of grid point (a, b, c) (φd fastest, like MERL).
    pub fn index(&self, a: usize, b: usize, c: usize) -> usize {
        let (_, nb, nc) = self.shape();
        c + nc * (b + nb * a)
    }

    /// Grid coordinates of a flat index.
    pub fn coords(&self, idx: usize) -> (usize, usize, usize) {
        let (_, nb, nc) = self.shape();
        (idx / (nb * nc), (idx / nc) % nb, idx % nc)
    }

    /// MERL bin of a grid point.
    pub fn merl_bin(&self, idx: usize) -> usize {
        let (a, b, c) = self.coords(idx);
        bin_index(
            a * self.theta_h_step,
            b * self.theta_d_step,
            c * self.phi_d_step,
        )
    }

    /// Angles (θh, θd, φd) of a grid point.
    pub fn angles(&self, idx: usize) -> (f64, f64, f64) {
        let (a, b, c) = self.coords(idx);
        bin_angles(
            a * self.theta_h_step,
            b * self.theta_d_step,
            c * self.phi_d_step,
        )
    }

    /// Nearest grid point of the angles (rounded in the grid's own parametrisation: √θh, θd,
    /// φd folded into [0, π) by reciprocity and wrapped).
    pub fn nearest(&self, theta_h: f64, theta_d: f64, phi_d: f64) -> usize {
        let (na, nb, nc) = self.shape();
        let [u_h, u_d, u_p] = grid_coordinates(theta_h, theta_d, phi_d);
        let a = ((u_h / self.theta_h_step as f64).round() as usize).min(na - 1);
        let b = ((u_d / self.theta_d_step as f64).round() as usize).min(nb - 1);
        let mut c = (u_p / self.phi_d_step as f64).round() as usize;
        // φd = π is φd = 0; a rounded index past the last grid point wraps to the nearer end.
        if c >= nc {
            let last = ((nc - 1) * self.phi_d_step) as f64;
            c = if u_p - last < PHI_D_RES as f64 - u_p {
                nc - 1
            } else {
                0
            };
        }
        self.index(a, b, c)
    }
}

/// RGB BRDF values (1/sr) on a [`SampleGrid`], channel-major (`3 × grid.len()`).
///
/// # Examples
///
/// ```
/// use brdf::analytic::Lambert;
/// use sampling::{GridTable, SampleGrid};
///
/// let grid = SampleGrid::new(9, 9, 18).unwrap();
/// let table = GridTable::tabulate(&Lambert { kd: [0.3; 3] }, grid);
/// // a Lambertian surface is kd/π at every point above the horizon
/// assert!((table.get(1, grid.index(2, 3, 4)) - 0.3 / std::f64::consts::PI).abs() < 1e-12);
/// ```
/// Negative values mark missing data.
#[derive(Debug, Clone, PartialEq)]
pub struct GridTable {
    /// The grid.
    pub grid: SampleGrid,
    /// Values, channel-major.
    pub values: Vec<f64>,
}

impl brdf::metrics::TableView for GridTable {
    fn points(&self) -> usize {
        self.grid.len()
    }
    fn value(&self, channel: usize, point: usize) -> f64 {
        self.get(channel, point)
    }
    fn angles(&self, point: usize) -> (f64, f64, f64) {
        self.grid.angles(point)
    }
    fn same_points(&self, other: &Self) -> bool {
        self.grid == other.grid
    }
}

impl GridTable {
    /// Wraps values; checks the length.
    pub fn new(grid: SampleGrid, values: Vec<f64>) -> Result<Self> {
        if values.len() != 3 * grid.len() {
            return Err(SamplingError::Dimension(format!(
                "grid table needs {} values, got {}",
                3 * grid.len(),
                values.len()
            )));
        }
        Ok(GridTable { grid, values })
    }

    /// Evaluates a BRDF at every grid point (in parallel).
    pub fn tabulate(brdf: &dyn Brdf, grid: SampleGrid) -> Self {
        let n = grid.len();
        let rgb: Vec<Rgb> = (0..n)
            .into_par_iter()
            .map(|i| {
                let (th, td, pd) = grid.angles(i);
                brdf.eval_half_diff(&HalfDiff::isotropic(th, td, pd))
            })
            .collect();
        Self::from_rgb(grid, &rgb)
    }

    /// Builds from per-point RGB triples.
    fn from_rgb(grid: SampleGrid, rgb: &[Rgb]) -> Self {
        let n = grid.len();
        let mut values = vec![0.0; 3 * n];
        for (i, v) in rgb.iter().enumerate() {
            for c in 0..3 {
                values[c * n + i] = v[c];
            }
        }
        GridTable { grid, values }
    }

    /// Evaluates a neural BRDF directly at the grid angles (much faster than full tabulation on
    /// coarse grids).
    pub fn from_nbrdf(nbrdf: &brdf::nbrdf::Nbrdf, grid: SampleGrid) -> Self {
        let rgb: Vec<Rgb> = (0..grid.len())
            .into_par_iter()
            .map(|i| {
                let (th, td, pd) = grid.angles(i);
                nbrdf.eval_angles(th, td, pd)
            })
            .collect();
        Self::from_rgb(grid, &rgb)
    }

    /// Takes the grid points out of a full MERL table.
    pub fn from_merl(table: &MerlTable, grid: SampleGrid) -> Self {
        let n = grid.len();
        let mut values = vec![0.0; 3 * n];
        for c in 0..3 {
            for i in 0..n {
                values[c * n + i] = table.get(c, grid.merl_bin(i));
            }
        }
        GridTable { grid, values }
    }

    /// Value of a channel at a grid point.
    pub fn get(&self, channel: usize, idx: usize) -> f64 {
        self.values[channel * self.grid.len() + idx]
    }

    /// Nearest-point lookup at angles.
    pub fn lookup(&self, theta_h: f64, theta_d: f64, phi_d: f64) -> Rgb {
        let i = self.grid.nearest(theta_h, theta_d, phi_d);
        [0, 1, 2].map(|c| self.get(c, i))
    }

    /// Converts to a full MERL table. Grid points are copied; on a sub-grid every MERL bin takes
    /// the value of its nearest grid point.
    pub fn to_merl(&self) -> Result<MerlTable> {
        let mut values = vec![0.0; 3 * brdf::BINS];
        for bin in 0..brdf::BINS {
            let (i, j, k) = brdf::bin_coords(bin);
            let (th, td, pd) = bin_angles(i, j, k);
            let idx = self.grid.nearest(th, td, pd);
            for c in 0..3 {
                values[c * brdf::BINS + bin] = self.get(c, idx);
            }
        }
        Ok(MerlTable::from_values(values)?)
    }
}

/// Nearest-grid-point lookup; zero below the horizon.
impl Brdf for GridTable {
    fn eval(&self, wi: &brdf::Vec3, wo: &brdf::Vec3) -> Rgb {
        if wi.z < 0.0 || wo.z < 0.0 {
            return [0.0; 3];
        }
        let hd = HalfDiff::from_directions(wi, wo);
        self.lookup(hd.theta_h, hd.theta_d, hd.phi_d)
    }

    fn eval_half_diff(&self, hd: &HalfDiff) -> Rgb {
        if !hd.above_horizon() {
            return [0.0; 3];
        }
        self.lookup(hd.theta_h, hd.theta_d, hd.phi_d)
    }

    fn name(&self) -> String {
        format!(
            "grid-table({},{},{})",
            self.grid.theta_h_step, self.grid.theta_d_step, self.grid.phi_d_step
        )
    }
}
