//! Sample plans, measured values, their CSV formats, and a simulated measurement.

use std::path::Path;

use brdf::{Brdf, HalfDiff};
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, StandardNormal};

use crate::error::{Result, SamplingError};
use crate::grid::SampleGrid;

/// Header line of a plan file.
pub const PLAN_HEADER: &str = "theta_h,theta_d,phi_d,channel";
/// Header line of a values file.
pub const VALUES_HEADER: &str = "theta_h,theta_d,phi_d,channel,value";

/// One BRDF value to measure: Rusinkiewicz angles (radians) and a colour channel.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SamplePoint {
    /// Half-vector polar angle θh.
    pub theta_h: f64,
    /// Difference-vector polar angle θd.
    pub theta_d: f64,
    /// Difference-vector azimuth φd.
    pub phi_d: f64,
    /// Colour channel (0 = R, 1 = G, 2 = B).
    pub channel: usize,
}

impl SamplePoint {
    /// The point at a grid point of `grid`.
    pub fn at_grid(grid: &SampleGrid, idx: usize, channel: usize) -> Self {
        let (theta_h, theta_d, phi_d) = grid.angles(idx);
        SamplePoint {
            theta_h,
            theta_d,
            phi_d,
            channel,
        }
    }

    fn validate(&self) -> std::result::Result<(), String> {
        if !(self.theta_h.is_finite() && self.theta_d.is_finite() && self.phi_d.is_finite()) {
            return Err("non-finite angle".into());
        }
        if self.channel > 2 {
            return Err(format!("channel {} not in 0..=2", self.channel));
        }
        Ok(())
    }
}

/// The points to measure, in order.
///
/// Plan CSV: header `theta_h,theta_d,phi_d,channel`, one point per line, angles in radians,
/// channel 0 = R, 1 = G, 2 = B. Values CSV: the same columns plus `value` (BRDF in 1/sr).
///
/// # Examples
///
/// ```
/// use sampling::{Plan, SamplePoint};
///
/// let plan = Plan {
///     points: vec![SamplePoint { theta_h: 0.1, theta_d: 0.5, phi_d: 1.5, channel: 2 }],
/// };
/// let path = std::env::temp_dir().join(format!("sampling-plan-doc-{}.csv", std::process::id()));
/// plan.write_csv(&path).unwrap();
/// let back = Plan::read_csv(&path).unwrap();
/// # std::fs::remove_file(&path).unwrap();
/// assert_eq!(back, plan);
/// ```
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Plan {
    /// Sample points.
    pub points: Vec<SamplePoint>,
}

impl Plan {
    /// Number of points.
    pub fn len(&self) -> usize {
        self.points.len()
    }

    /// Whether the plan has no points.
    pub fn is_empty(&self) -> bool {
        self.points.is_empty()
    }

    /// Rows `(grid point, channel)` of the plan on a grid (nearest grid point).
    pub fn rows(&self, grid: &SampleGrid) -> Vec<(usize, usize)> {
        self.points
            .iter()
            .map(|p| (grid.nearest(p.theta_h, p.theta_d, p.phi_d), p.channel))
            .collect()
    }

    /// Writes the plan CSV atomically.
    pub fn write_csv(&self, path: impl AsRef<Path>) -> Result<()> {
        let mut s = String::with_capacity(64 * self.points.len() + 32);
        s.push_str(PLAN_HEADER);
        s.push('\n');
        for p in &self.points {
            s.push_str(&format!(
                "{:?},{:?},{:?},{}\n",
                p.theta_h, p.theta_d, p.phi_d, p.channel
            ));
        }
        write_atomic(path.as_ref(), s.as_bytes())
    }

    /// Reads a plan CSV.
    pub fn read_csv(path: impl AsRef<Path>) -> Result<Plan> {
        let rows = read_rows(path.as_ref(), PLAN_HEADER, 4)?;
        Ok(Plan {
            points: rows.into_iter().map(|(p, _)| p).collect(),
        })
    }
}

/// Measured values at the points of a plan.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Measurements {
    /// The points.
    pub points: Vec<SamplePoint>,
    /// BRDF values (1/sr), one per point.
    pub values: Vec<f64>,
}

impl Measurements {
    /// Pairs points and values; checks lengths and finiteness.
    pub fn new(points: Vec<SamplePoint>, values: Vec<f64>) -> Result<Self> {
        if points.len() != values.len() {
            return Err(SamplingError::Dimension(format!(
                "{} points but {} values",
                points.len(),
                values.len()
            )));
        }
        if let Some(v) = values.iter().find(|v| !v.is_finite()) {
            return Err(SamplingError::NonFinite(format!("measured value {v}")));
        }
        Ok(Measurements { points, values })
    }

    /// The plan the values belong to.
    pub fn plan(&self) -> Plan {
        Plan {
            points: self.points.clone(),
        }
    }

    /// The values as (grid point, channel, value) samples, each point snapped to its nearest
    /// point of `grid` ([`Plan::rows`]).
    pub fn grid_samples(&self, grid: &SampleGrid) -> Vec<(usize, usize, f64)> {
        self.points
            .iter()
            .zip(&self.values)
            .map(|(p, &v)| (grid.nearest(p.theta_h, p.theta_d, p.phi_d), p.channel, v))
            .collect()
    }

    /// Writes the values CSV atomically.
    pub fn write_csv(&self, path: impl AsRef<Path>) -> Result<()> {
        let mut s = String::with_capacity(80 * self.points.len() + 40);
        s.push_str(VALUES_HEADER);
        s.push('\n');
        for (p, v) in self.points.iter().zip(&self.values) {
            s.push_str(&format!(
                "{:?},{:?},{:?},{},{:?}\n",
                p.theta_h, p.theta_d, p.phi_d, p.channel, v
            ));
        }
        write_atomic(path.as_ref(), s.as_bytes())
    }

    /// Reads a values CSV.
    pub fn read_csv(path: impl AsRef<Path>) -> Result<Measurements> {
        let rows = read_rows(path.as_ref(), VALUES_HEADER, 5)?;
        let (points, values) = rows.into_iter().unzip();
        Ok(Measurements { points, values })
    }
}

/// Writes `bytes` to a temporary file in the same directory, then renames it onto `path`.
pub fn write_atomic(path: &Path, bytes: &[u8]) -> Result<()> {
    Ok(brdf::write_atomic(path, bytes)?)
}

fn read_rows(path: &Path, header: &str, columns: usize) -> Result<Vec<(SamplePoint, f64)>> {
    let text = std::fs::read_to_string(path).map_err(|e| SamplingError::io(path, e))?;
    let bad = |line: usize, reason: String| SamplingError::MalformedCsv {
        path: path.to_path_buf(),
        line,
        reason,
    };
    let mut lines = text.lines().enumerate();
    match lines.next() {
        Some((_, h)) if h.trim() == header => {}
        Some((_, h)) => return Err(bad(1, format!("expected header `{header}`, got `{h}`"))),
        None => return Err(bad(1, "empty file".into())),
    }
    let mut out = Vec::new();
    for (i, line) in lines {
        let line_no = i + 1;
        if line.trim().is_empty() {
            continue;
        }
        let fields: Vec<&str> = line.split(',').map(str::trim).collect();
        if fields.len() != columns {
            return Err(bad(
                line_no,
                format!("expected {columns} fields, got {}", fields.len()),
            ));
        }
        let num = |k: usize| -> Result<f64> {
            fields[k]
                .parse::<f64>()
                .map_err(|e| bad(line_no, format!("field {}: {e}", k + 1)))
        };
        let channel = fields[3]
            .parse::<usize>()
            .map_err(|e| bad(line_no, format!("channel: {e}")))?;
        let p = SamplePoint {
            theta_h: num(0)?,
            theta_d: num(1)?,
            phi_d: num(2)?,
            channel,
        };
        p.validate().map_err(|r| bad(line_no, r))?;
        let value = if columns == 5 {
            let v = num(4)?;
            if !v.is_finite() {
                return Err(bad(line_no, "non-finite value".into()));
            }
            v
        } else {
            0.0
        };
        out.push((p, value));
    }
    Ok(out)
}

/// Simulated planar-sample gonioreflectometer: evaluates `material` at every point of `plan`
/// (directions from the Rusinkiewicz angles with φh = 0) and multiplies each value by
/// `exp(noise · z)`, z standard normal from a ChaCha8 stream seeded with `seed`.
/// Configurations with a direction below the horizon read 0, as a planar sample would.
///
/// # Examples
///
/// ```
/// use brdf::analytic::Lambert;
/// use sampling::{measure_plan, Plan, SamplePoint};
///
/// let plan = Plan {
///     points: vec![SamplePoint { theta_h: 0.1, theta_d: 0.2, phi_d: 1.0, channel: 0 }],
/// };
/// // without noise the measured value is the BRDF value
/// let m = measure_plan(&plan, &Lambert { kd: [0.5; 3] }, 0.0, 1).unwrap();
/// assert!((m.values[0] - 0.5 / std::f64::consts::PI).abs() < 1e-12);
/// ```
pub fn measure_plan(
    plan: &Plan,
    material: &dyn Brdf,
    noise: f64,
    seed: u64,
) -> Result<Measurements> {
    if !(noise.is_finite() && noise >= 0.0) {
        return Err(SamplingError::InvalidParameter(format!(
            "noise level {noise} must be finite and ≥ 0"
        )));
    }
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let mut values = Vec::with_capacity(plan.len());
    for p in &plan.points {
        p.validate().map_err(SamplingError::InvalidParameter)?;
        let rgb = material.eval_half_diff(&HalfDiff::isotropic(p.theta_h, p.theta_d, p.phi_d));
        let z: f64 = StandardNormal.sample(&mut rng);
        let v = rgb[p.channel].max(0.0) * (noise * z).exp();
        values.push(v);
    }
    Measurements::new(plan.points.clone(), values)
}
