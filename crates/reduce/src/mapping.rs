//! Transforms of BRDF values into the space a linear model is fitted in.
//!
//! The thesis's model (§4.1) is linear in `ln(f + ε)`. Nielsen et al. 2015 map values first by
//! the product of the two cosines, `ln(f cos θi cos θo + ε)` (divided by the same expression of a
//! reference material, a constant per entry that the PCA's mean absorbs): the grazing entries,
//! where a measured table is least reliable and a rendering least sensitive, weigh less.
//! [`Mapping`] names the transform; every corpus vector is stored in the thesis's log space
//! ([`to_log`](crate::to_log)), and a mapping converts from it.

use std::sync::OnceLock;

use rayon::prelude::*;

use crate::corpus::LOG_FLOOR;
use crate::error::{ReduceError, Result};

/// Cosines below this are raised to it in [`Mapping::CosineLog`] (both directions 84° from
/// the normal): below-horizon entries and the last grazing ones share one weight instead of
/// dividing by zero on the way back.
pub const MIN_COSINE_PRODUCT: f64 = 1e-2;

/// The transform of BRDF values `f` (1/sr) before the linear model.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub enum Mapping {
    /// `ln(f + ε)` with ε = [`LOG_FLOOR`] (thesis §4.1).
    #[default]
    Log,
    /// `ln(f c + ε)` with `c = max(cos θi cos θo, MIN_COSINE_PRODUCT)` of the entry's bin
    /// (Nielsen et al. 2015's mapping; their reference material is left out because the mean
    /// absorbs it).
    CosineLog {
        /// The floor ε.
        epsilon: f64,
    },
}

impl Mapping {
    /// Nielsen et al. 2015's mapping with ε = [`LOG_FLOOR`].
    pub const COSINE: Mapping = Mapping::CosineLog { epsilon: LOG_FLOOR };

    /// Parses `log` or `cosine-log` (optionally `cosine-log:EPSILON`).
    pub fn parse(s: &str) -> Result<Mapping> {
        let bad = || {
            ReduceError::InvalidParameter(format!(
                "unknown mapping {s:?} (expected log, cosine-log or cosine-log:EPSILON)"
            ))
        };
        match s {
            "log" => Ok(Mapping::Log),
            "cosine-log" => Ok(Mapping::COSINE),
            _ => {
                let eps: f64 = s
                    .strip_prefix("cosine-log:")
                    .ok_or_else(bad)?
                    .parse()
                    .map_err(|_| bad())?;
                if !(eps.is_finite() && eps > 0.0) {
                    return Err(ReduceError::InvalidParameter(format!(
                        "the mapping's floor must be positive, got {eps}"
                    )));
                }
                Ok(Mapping::CosineLog { epsilon: eps })
            }
        }
    }

    /// Short name (`log`, `cosine-log`, `cosine-log:ε`), as [`Mapping::parse`] reads it.
    pub fn name(&self) -> String {
        match *self {
            Mapping::Log => "log".into(),
            Mapping::CosineLog { epsilon } if epsilon == LOG_FLOOR => "cosine-log".into(),
            Mapping::CosineLog { epsilon } => format!("cosine-log:{epsilon}"),
        }
    }

    /// Maps a vector in the thesis's log space (`ln(f + LOG_FLOOR)`, channel-major on the
    /// MERL grid for [`Mapping::CosineLog`]) in place.
    pub fn from_log_in_place(&self, y: &mut [f32]) -> Result<()> {
        let Mapping::CosineLog { epsilon } = *self else {
            return Ok(());
        };
        let c = cosine_products(y.len())?;
        let bins = c.len();
        y.par_chunks_mut(4096).enumerate().for_each(|(chunk, ys)| {
            for (o, v) in ys.iter_mut().enumerate() {
                let b = (chunk * 4096 + o) % bins;
                let f = ((*v as f64).exp() - LOG_FLOOR).max(0.0);
                *v = (f * c[b] as f64 + epsilon).ln() as f32;
            }
        });
        Ok(())
    }

    /// The inverse in closed form: entry `i` of a mapped vector (3 channels of the MERL grid,
    /// channel-major) with value `z` is the BRDF value `(exp(z) − floor) / w[i % BINS]`
    /// (before the clamp at 0). Returns `floor` and the per-bin weights `w`, `None` where they
    /// are all 1 ([`Mapping::Log`]). Consumers that differentiate the decoded values (a fit
    /// through the model) use it: `∂f/∂z = exp(z) / w`.
    pub fn inverse_form(&self) -> (f64, Option<&'static [f32]>) {
        match *self {
            Mapping::Log => (LOG_FLOOR, None),
            Mapping::CosineLog { epsilon } => (
                epsilon,
                Some(cosine_products(brdf::MATERIAL_DIM).expect("the MERL grid's length")),
            ),
        }
    }

    /// BRDF values (clamped to ≥ 0) of a mapped vector.
    pub fn to_values(&self, z: &[f32]) -> Result<Vec<f64>> {
        match *self {
            Mapping::Log => Ok(z.par_iter().map(|&v| crate::from_log(v).max(0.0)).collect()),
            Mapping::CosineLog { epsilon } => {
                let c = cosine_products(z.len())?;
                let bins = c.len();
                Ok(z.par_iter()
                    .enumerate()
                    .map(|(i, &v)| (((v as f64).exp() - epsilon) / c[i % bins] as f64).max(0.0))
                    .collect())
            }
        }
    }
}

/// `max(cos θi cos θo, MIN_COSINE_PRODUCT)` per MERL bin (computed once); a vector that is
/// not three channels of the MERL grid is an error.
fn cosine_products(len: usize) -> Result<&'static [f32]> {
    if len != brdf::MATERIAL_DIM {
        return Err(ReduceError::Dimension {
            what: "vector length of a cosine-mapped material (3 channels of the MERL grid)",
            expected: brdf::MATERIAL_DIM,
            got: len,
        });
    }
    static C: OnceLock<Vec<f32>> = OnceLock::new();
    Ok(C.get_or_init(|| {
        (0..brdf::BINS)
            .into_par_iter()
            .map(|b| {
                let (i, j, k) = brdf::bin_coords(b);
                let (th, td, pd) = brdf::bin_angles(i, j, k);
                let (wi, wo) = brdf::HalfDiff::isotropic(th, td, pd).to_directions();
                (wi.z * wo.z).max(MIN_COSINE_PRODUCT) as f32
            })
            .collect()
    }))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_inverse_form_is_the_inverse() {
        let z: Vec<f32> = (0..brdf::MATERIAL_DIM)
            .map(|i| ((i * 7919) % 1000) as f32 / 250.0 - 3.0)
            .collect();
        for m in [Mapping::Log, Mapping::COSINE] {
            let v = m.to_values(&z).unwrap();
            let (floor, w) = m.inverse_form();
            for i in (0..z.len()).step_by(997) {
                let d = w.map_or(1.0, |w| w[i % brdf::BINS] as f64);
                let want = (((z[i] as f64).exp() - floor) / d).max(0.0);
                assert!((v[i] - want).abs() <= 1e-9 * want.max(1.0), "{m:?} {i}");
            }
        }
    }

    #[test]
    fn names_parse_back_and_bad_ones_are_refused() {
        for m in [
            Mapping::Log,
            Mapping::COSINE,
            Mapping::CosineLog { epsilon: 0.01 },
        ] {
            assert_eq!(Mapping::parse(&m.name()).unwrap(), m);
        }
        for bad in ["", "cos", "cosine-log:", "cosine-log:-1", "cosine-log:nan"] {
            assert!(Mapping::parse(bad).is_err(), "{bad}");
        }
    }

    #[test]
    fn cosine_mapping_round_trips_a_table_and_weighs_grazing_entries_less() {
        let table = brdf::MerlTable::tabulate(&brdf::analytic::Ggx {
            kd: [0.1, 0.2, 0.3],
            ks: [0.2; 3],
            alpha: 0.2,
            ior: 1.5,
        });
        let values = table.values();
        let mut z = crate::log_vector(&values).unwrap();
        let m = Mapping::COSINE;
        m.from_log_in_place(&mut z).unwrap();
        let back = m.to_values(&z).unwrap();
        let c = cosine_products(values.len()).unwrap();
        for (i, (&v, &b)) in values.iter().zip(&back).enumerate() {
            let v = v.max(0.0);
            // f32 storage: relative error of the mapped value's exponent, amplified by ε/(fc)
            let tol = 1e-5 * (v + 2.0 * LOG_FLOOR / c[i % brdf::BINS] as f64);
            assert!((v - b).abs() <= tol, "{i}: {v} vs {b}");
        }
        // a change of 1 % of a value moves its mapped value less at grazing angles than at
        // normal incidence (the plain log moves both alike)
        let normal = brdf::bin_index(0, 0, 0);
        let grazing = (0..brdf::BINS)
            .find(|&b| (c[b] as f64) < MIN_COSINE_PRODUCT + 1e-6 && values[b] > 0.0)
            .unwrap();
        assert!(c[normal] > 0.99, "{}", c[normal]);
        let f = 0.05;
        let dz = |b: usize| {
            let cz = |f: f64| (f * c[b] as f64 + LOG_FLOOR).ln();
            cz(1.01 * f) - cz(f)
        };
        assert!(
            dz(grazing) < 0.5 * dz(normal),
            "{} vs {}",
            dz(grazing),
            dz(normal)
        );
        assert!(m.to_values(&z[..10]).is_err());
    }
}
