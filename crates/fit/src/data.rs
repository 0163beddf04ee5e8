//! Measured data prepared for fitting.

use crate::error::{FitError, Result};
use crate::model::Geom;
use brdf::analytic::PairGeometry;
use brdf::{bin_angles, bin_coords, BINS, PHI_D_RES, THETA_D_RES, THETA_H_RES};
use brdf::{HalfDiff, MerlTable, Rgb, Vec3};
use rand::seq::SliceRandom;
use rand::SeedableRng;
use rayon::prelude::*;
use sampling::{GridTable, SampleGrid};
use std::f64::consts::{FRAC_PI_2, PI};
use std::sync::{Arc, OnceLock};

/// Grazing cut of Ngan's metric: bins with θi or θo above 80° are left out.
pub const NGAN_MAX_THETA_DEG: f64 = 80.0;

/// Floor added before taking logarithms, in 1/sr (the same as `sampling`'s `LOG_FLOOR`).
pub const LOG_FLOOR: f64 = sampling::LOG_FLOOR;

/// Geometry of every MERL bin whose two directions lie above the horizon.
#[derive(Debug)]
pub struct GridGeometry {
    /// Flat MERL bin index of each entry.
    pub bins: Vec<u32>,
    /// Direction-pair geometry of each entry.
    pub geoms: Arc<Vec<Geom>>,
    /// Solid-angle measure of each bin (∝ cos θd sin θh sin θd Δθh Δθd Δφd).
    pub measure: Vec<f64>,
    /// cos θi of each entry.
    pub cos_i: Vec<f64>,
    /// Whether θi and θo are both ≤ [`NGAN_MAX_THETA_DEG`].
    pub below_grazing: Vec<bool>,
}

/// The grid geometry, computed on first use (about a million bins, in parallel).
pub fn grid_geometry() -> &'static GridGeometry {
    static CACHE: OnceLock<GridGeometry> = OnceLock::new();
    CACHE.get_or_init(|| {
        let cut = NGAN_MAX_THETA_DEG.to_radians().cos();
        let d_td = FRAC_PI_2 / THETA_D_RES as f64;
        let d_pd = PI / PHI_D_RES as f64;
        let entries: Vec<(u32, Geom, f64, f64, bool)> = (0..BINS)
            .into_par_iter()
            .filter_map(|bin| {
                let (i, j, k) = bin_coords(bin);
                let (th, td, pd) = bin_angles(i, j, k);
                let (wi, wo) = HalfDiff::isotropic(th, td, pd).to_directions();
                let g = Geom::new(&wi, &wo)?;
                // θh = (i/90)² π/2, so dθh/di = 2i/90² · π/2.
                let d_th = 2.0 * i as f64 / (THETA_H_RES * THETA_H_RES) as f64 * FRAC_PI_2;
                let measure = 4.0 * td.cos() * th.sin() * td.sin() * d_th * d_td * d_pd;
                Some((bin as u32, g, measure, wi.z, wi.z >= cut && wo.z >= cut))
            })
            .collect();
        GridGeometry {
            bins: entries.iter().map(|e| e.0).collect(),
            geoms: Arc::new(entries.iter().map(|e| e.1).collect()),
            measure: entries.iter().map(|e| e.2).collect(),
            cos_i: entries.iter().map(|e| e.3).collect(),
            below_grazing: entries.iter().map(|e| e.4).collect(),
        }
    })
}

/// What was left out of a table, and why.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, serde::Serialize)]
pub struct Exclusions {
    /// Bins of the grid.
    pub bins: usize,
    /// Bins with a direction at or below the horizon (no reflection is defined there).
    pub below_horizon: usize,
    /// Bins with a missing (negative) value in some channel.
    pub missing: usize,
    /// Bins with a NaN or infinite value in some channel.
    pub non_finite: usize,
    /// Bins used.
    pub valid: usize,
}

/// One measured table prepared for fitting: its valid bins (NaN and missing bins excluded and
/// counted) and the rows an objective is built from. The bin geometry of the MERL grid is
/// computed once per process and shared by every table ([`grid_geometry`]).
///
/// # Examples
///
/// ```
/// use fit::FitData;
/// // A Lambertian table: every bin above the horizon holds kd/π.
/// let mut table = brdf::load("lambert:kd=0.5").unwrap().tabulate();
/// // Mark one bin missing (negative) and another non-finite.
/// let bins = fit::grid_geometry().bins.clone();
/// table.set(0, bins[0] as usize, -1.0);
/// table.set(1, bins[1] as usize, f64::NAN);
/// let data = FitData::new(&table).unwrap();
/// let x = data.exclusions;
/// assert_eq!((x.missing, x.non_finite), (1, 1));
/// assert_eq!(x.valid + x.missing + x.non_finite + x.below_horizon, x.bins);
/// assert_eq!(data.values.len(), x.valid);
/// // The diffuse estimate (π × mean value at grazing half angles) recovers kd.
/// let kd = data.diffuse_estimate();
/// assert!(kd.iter().all(|c| (c - 0.5).abs() < 1e-3), "{kd:?}");
/// ```
#[derive(Debug, Clone)]
pub struct FitData {
    /// Index into [`grid_geometry`] of each valid bin.
    pub entries: Vec<u32>,
    /// Measured RGB of each valid bin (1/sr).
    pub values: Vec<Rgb>,
    /// Counts of excluded bins.
    pub exclusions: Exclusions,
    /// Reference sphere image of the table (`sampling::metrics::render_sphere`).
    pub sphere: Vec<Rgb>,
    /// Side of the sphere image in pixels.
    pub sphere_size: usize,
    /// [`FitData::diffuse_estimate`], computed once (every fit's default start reads it).
    diffuse: Rgb,
}

/// Side of the rendered-sphere images (as in the sampling study).
pub const SPHERE_SIZE: usize = 64;

impl FitData {
    /// Collects the valid bins of `table`: finite, non-negative in all three channels, both
    /// directions above the horizon. Everything else is counted in [`FitData::exclusions`].
    pub fn new(table: &MerlTable) -> Result<FitData> {
        let geo = grid_geometry();
        let mut ex = Exclusions {
            bins: BINS,
            below_horizon: BINS - geo.bins.len(),
            ..Default::default()
        };
        let mut entries = Vec::with_capacity(geo.bins.len());
        let mut values = Vec::with_capacity(geo.bins.len());
        for (e, &bin) in geo.bins.iter().enumerate() {
            let v = [
                table.get(0, bin as usize),
                table.get(1, bin as usize),
                table.get(2, bin as usize),
            ];
            if v.iter().any(|x| !x.is_finite()) {
                ex.non_finite += 1;
            } else if v.iter().any(|x| *x < 0.0) {
                ex.missing += 1;
            } else {
                entries.push(e as u32);
                values.push(v);
            }
        }
        ex.valid = entries.len();
        if entries.is_empty() {
            return Err(FitError::NoData("the table has no valid bin".into()));
        }
        // The sampling metric's reference image (it reads missing and NaN values as 0).
        let gt = GridTable::from_merl(table, SampleGrid::new(1, 1, 1)?);
        let sphere = sampling::metrics::render_sphere(&gt, SPHERE_SIZE);
        let diffuse = diffuse_estimate(geo, &entries, &values);
        Ok(FitData {
            entries,
            values,
            exclusions: ex,
            sphere,
            sphere_size: SPHERE_SIZE,
            diffuse,
        })
    }

    /// Mean measured value per channel times π over bins with θh > 45° (an estimate of the
    /// diffuse albedo, used for the default start), computed by [`FitData::new`] from the bins
    /// it collected (edits of the public fields afterwards do not change it).
    pub fn diffuse_estimate(&self) -> Rgb {
        self.diffuse
    }
}

/// [`FitData::diffuse_estimate`] of the valid bins `entries` with their `values`.
fn diffuse_estimate(geo: &GridGeometry, entries: &[u32], values: &[Rgb]) -> Rgb {
    let mut s = [0.0; 3];
    let mut n = 0usize;
    for (e, v) in entries.iter().zip(values) {
        if geo.geoms[*e as usize].h_z() < std::f64::consts::FRAC_1_SQRT_2 {
            for c in 0..3 {
                s[c] += v[c];
            }
            n += 1;
        }
    }
    let n = n.max(1) as f64;
    [s[0] / n * PI, s[1] / n * PI, s[2] / n * PI]
}

/// Which valid bins an objective uses.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Subset {
    /// Every valid bin.
    All,
    /// `bins` valid bins drawn without replacement with a seeded generator (the thesis used
    /// 2,000 bins, i.e. 6,000 values over three channels).
    Random {
        /// Number of bins.
        bins: usize,
        /// Seed of the draw.
        seed: u64,
    },
}

impl Subset {
    /// Indices into [`FitData::entries`] of the selected bins (sorted).
    pub fn select(self, n: usize) -> Vec<usize> {
        match self {
            Subset::All => (0..n).collect(),
            Subset::Random { bins, seed } => {
                let mut idx: Vec<usize> = (0..n).collect();
                if bins >= n {
                    return idx;
                }
                let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed);
                let (chosen, _) = idx.partial_shuffle(&mut rng, bins);
                let mut chosen = chosen.to_vec();
                chosen.sort_unstable();
                chosen
            }
        }
    }
}

/// The rows of a least-squares problem: each row predicts an RGB value as a weighted sum of
/// model evaluations (one term for a bin, one per light for a sphere pixel) and compares it with
/// a target, linearly or in log space.
#[derive(Debug, Clone)]
pub struct Rows {
    /// Geometry the terms index into.
    pub geoms: Arc<Vec<Geom>>,
    /// Geometry index of each term.
    pub term_geom: Vec<u32>,
    /// Weight of each term.
    pub term_weight: Vec<f64>,
    /// Row `r` owns terms `row_start[r]..row_start[r + 1]`.
    pub row_start: Vec<u32>,
    /// Target of each row (already in log space for log rows).
    pub targets: Vec<Rgb>,
    /// Whether residuals are `ln(prediction + floor) − target`.
    pub log: bool,
    /// Σ over rows and channels of the squared reference size (the error's denominator).
    pub norm2: f64,
}

impl Rows {
    /// Number of rows.
    pub fn len(&self) -> usize {
        self.targets.len()
    }

    /// Whether there are no rows.
    pub fn is_empty(&self) -> bool {
        self.targets.is_empty()
    }

    /// Thesis §3.7's log-space rows: residual ln(f̂ + 10⁻³) − ln(f + 10⁻³) per bin and channel;
    /// the error's denominator is Σ (ln(f + 10⁻³) − ln 10⁻³)², as `sampling::metrics::log_rms_relative`.
    pub fn log(data: &FitData, subset: Subset) -> Result<Rows> {
        let geo = grid_geometry();
        let sel = subset.select(data.entries.len());
        let mut rows = Rows::empty(geo.geoms.clone(), true);
        for i in sel {
            let v = data.values[i];
            let t = v.map(brdf::to_log);
            rows.norm2 += t.iter().map(|y| (y - LOG_FLOOR.ln()).powi(2)).sum::<f64>();
            rows.push(&[(data.entries[i], 1.0)], t);
        }
        rows.finish()
    }

    /// Ngan et al.'s rows: √w · (f̂ − f) · cos θi per bin and channel, w the bin's solid-angle
    /// measure, bins with θi or θo above 80° left out; the denominator is Σ w (f cos θi)².
    pub fn ngan(data: &FitData, subset: Subset) -> Result<Rows> {
        let geo = grid_geometry();
        let sel = subset.select(data.entries.len());
        let mut rows = Rows::empty(geo.geoms.clone(), false);
        for i in sel {
            let e = data.entries[i] as usize;
            if !geo.below_grazing[e] || geo.measure[e] <= 0.0 {
                continue;
            }
            let s = geo.measure[e].sqrt() * geo.cos_i[e];
            let v = data.values[i];
            let t = [v[0] * s, v[1] * s, v[2] * s];
            rows.norm2 += t.iter().map(|y| y * y).sum::<f64>();
            rows.push(&[(e as u32, s)], t);
        }
        rows.finish()
    }

    /// Rendered-sphere rows: one per lit pixel of the sampling crate's sphere image (four point
    /// lights, orthographic view), residual Î − I; the denominator is Σ I².
    pub fn sphere(data: &FitData) -> Result<Rows> {
        let size = data.sphere_size;
        let lights = sampling::metrics::sphere_lights();
        let view = Vec3::new(0.0, 0.0, 1.0);
        let mut geoms = Vec::new();
        let mut rows = Rows::empty(Arc::new(Vec::new()), false);
        // The same pixels and shading frames as `sampling::metrics::render_sphere`.
        for pixel in brdf::sphere_pixels(size) {
            let n = pixel.normal;
            let local = |w: &Vec3| pixel.to_local(w);
            let wo = local(&view);
            let mut terms = Vec::new();
            for l in &lights {
                let cos = l.dot(&n);
                if cos <= 0.0 {
                    continue;
                }
                if let Some(g) = Geom::new(&local(l), &wo) {
                    terms.push((geoms.len() as u32, cos));
                    geoms.push(g);
                }
            }
            if terms.is_empty() {
                continue;
            }
            let target = data.sphere[pixel.index];
            rows.norm2 += target.iter().map(|v| v * v).sum::<f64>();
            rows.push(&terms, target);
        }
        rows.geoms = Arc::new(geoms);
        rows.finish()
    }

    fn empty(geoms: Arc<Vec<Geom>>, log: bool) -> Rows {
        Rows {
            geoms,
            term_geom: Vec::new(),
            term_weight: Vec::new(),
            row_start: vec![0],
            targets: Vec::new(),
            log,
            norm2: 0.0,
        }
    }

    fn push(&mut self, terms: &[(u32, f64)], target: Rgb) {
        for &(g, w) in terms {
            self.term_geom.push(g);
            self.term_weight.push(w);
        }
        self.row_start.push(self.term_geom.len() as u32);
        self.targets.push(target);
    }

    fn finish(self) -> Result<Rows> {
        if self.is_empty() || self.norm2 <= 0.0 {
            return Err(FitError::NoData(
                "no valid rows (or an all-zero reference)".into(),
            ));
        }
        Ok(self)
    }
}
