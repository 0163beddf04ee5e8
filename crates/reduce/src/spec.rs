//! `pca:` material specs: points of a PCA model's space as materials (thesis §4.2).

use crate::error::{ReduceError, Result};
use crate::model::Model;
use brdf::MerlTable;
use brdf::{Material, SpecResolver};
use std::path::{Path, PathBuf};
use std::sync::{Arc, Mutex};

/// The spec prefix: `pca:<model.bin>?…`.
pub const SPEC_PREFIX: &str = "pca";

/// Which point of the model's space a `pca:` spec names.
#[derive(Debug, Clone, PartialEq)]
pub enum PcaPoint {
    /// The mean.
    Mean,
    /// Explicit coordinates on the first components.
    Coordinates(Vec<f64>),
    /// A material of the model's corpus, truncated to `k` components (all when `None`).
    Material {
        /// Its name in the model.
        name: String,
        /// Components kept.
        k: Option<usize>,
    },
    /// A material spec projected onto the first `k` components (all when `None`).
    Projection {
        /// The material spec.
        spec: String,
        /// Components kept.
        k: Option<usize>,
    },
}

/// A parsed `pca:` spec (the part after `pca:`): a point of a PCA model's space as a material
/// (thesis §4.2).
///
/// | form | material |
/// |---|---|
/// | `pca:<model.bin>` | the mean of the model |
/// | `pca:<model.bin>?c=<x1>/<x2>/…` | the point with coordinates `x1, x2, …` on the first components |
/// | `pca:<model.bin>?material=<name>[&k=<K>]` | a material of the model's corpus, on its first `K` components (default all) |
/// | `pca:<model.bin>?of=<spec>[&k=<K>]` | any material spec projected onto the first `K` components (default all) |
///
/// Coordinates are those of [`Pca::project`](crate::Pca::project) (log space, thesis eq. 4.3); the
/// material is the table `max(exp(mean + Σ xₖ uₖ) − ε, 0)` on the MERL grid. The model must be
/// built on full MERL tables. A relative model path is relative to the working directory.
/// [`register_spec_resolver`] makes the form available to every spec-taking function.
///
/// # Examples
///
/// ```
/// use reduce::{PcaPoint, PcaSpec};
///
/// let s = PcaSpec::parse("model.bin?of=merl:chrome&k=10").unwrap();
/// assert_eq!(s.model, std::path::PathBuf::from("model.bin"));
/// assert_eq!(s.point, PcaPoint::Projection { spec: "merl:chrome".into(), k: Some(10) });
/// assert_eq!(PcaSpec::parse("m.bin?c=0.5/-1").unwrap().point, PcaPoint::Coordinates(vec![0.5, -1.0]));
/// assert!(PcaSpec::parse("m.bin?c=0.5&of=merl:chrome").is_err());
/// ```
#[derive(Debug, Clone, PartialEq)]
pub struct PcaSpec {
    /// The model file.
    pub model: PathBuf,
    /// The point.
    pub point: PcaPoint,
}

fn bad(msg: impl Into<String>) -> ReduceError {
    ReduceError::InvalidParameter(msg.into())
}

impl PcaSpec {
    /// Parses `<model.bin>[?key=value&…]` (the spec without its `pca:` prefix).
    pub fn parse(rest: &str) -> Result<PcaSpec> {
        let (model, query) = match rest.split_once('?') {
            Some((m, q)) => (m.trim(), Some(q)),
            None => (rest.trim(), None),
        };
        if model.is_empty() {
            return Err(bad("expected pca:<model.bin>[?…]"));
        }
        let mut c = None;
        let mut material = None;
        let mut of = None;
        let mut k = None;
        for kv in query.into_iter().flat_map(|q| q.split('&')) {
            let (key, value) = kv
                .split_once('=')
                .ok_or_else(|| bad(format!("'{kv}' is not key=value")))?;
            let value = value.trim();
            let slot = match key.trim() {
                "c" => &mut c,
                "material" => &mut material,
                "of" => &mut of,
                "k" => &mut k,
                other => {
                    return Err(bad(format!(
                        "unknown key '{other}' (expected c, material, of or k)"
                    )))
                }
            };
            if slot.replace(value.to_string()).is_some() {
                return Err(bad(format!("'{}' given twice", key.trim())));
            }
        }
        let k = k
            .map(|v| {
                v.parse::<usize>()
                    .ok()
                    .filter(|&k| k > 0)
                    .ok_or_else(|| bad(format!("k={v}: expected a positive integer")))
            })
            .transpose()?;
        let point = match (c, material, of) {
            (None, None, None) if k.is_none() => PcaPoint::Mean,
            (Some(c), None, None) if k.is_none() => PcaPoint::Coordinates(
                c.split('/')
                    .filter(|s| !s.trim().is_empty())
                    .map(|s| {
                        s.trim()
                            .parse::<f64>()
                            .ok()
                            .filter(|x| x.is_finite())
                            .ok_or_else(|| bad(format!("c: '{s}' is not a finite number")))
                    })
                    .collect::<Result<_>>()?,
            ),
            (None, Some(name), None) if !name.is_empty() => PcaPoint::Material { name, k },
            (None, None, Some(spec)) if !spec.is_empty() => PcaPoint::Projection { spec, k },
            _ => {
                return Err(bad(
                    "give one of c=<x1>/<x2>/…, material=<name> or of=<spec> \
                     (k only with material or of)",
                ))
            }
        };
        Ok(PcaSpec {
            model: PathBuf::from(model),
            point,
        })
    }

    /// The coordinates of the point in `model`'s space.
    pub fn coordinates(&self, model: &Model) -> Result<Vec<f64>> {
        let all = model.components();
        let k_of = |k: Option<usize>| -> Result<usize> {
            match k {
                Some(k) if k > all => Err(ReduceError::Dimension {
                    what: "components of a pca: spec (at most the model's)",
                    expected: all,
                    got: k,
                }),
                Some(k) => Ok(k),
                None => Ok(all),
            }
        };
        match &self.point {
            PcaPoint::Mean => Ok(Vec::new()),
            PcaPoint::Coordinates(x) => Ok(x.clone()),
            PcaPoint::Material { name, k } => {
                let k = k_of(*k)?;
                let i = model.names.iter().position(|n| n == name).ok_or_else(|| {
                    bad(format!(
                        "{}: no material '{name}' in the model",
                        self.model.display()
                    ))
                })?;
                Ok((0..k).map(|j| model.pca.coords[(i, j)]).collect())
            }
            PcaPoint::Projection { spec, k } => {
                let k = k_of(*k)?;
                let table = brdf::load(spec)?.tabulate();
                model.project_values(&table.values(), k)
            }
        }
    }

    /// The material on the MERL grid.
    pub fn table(&self, model: &Model) -> Result<MerlTable> {
        ReduceError::check_size(
            "model dimension (a pca: material needs a model of full MERL tables)",
            brdf::MATERIAL_DIM,
            model.pca.dim,
        )?;
        let x = self.coordinates(model)?;
        Ok(MerlTable::from_values(model.synthesize(&x)?)?.with_name(self.name()))
    }

    fn name(&self) -> String {
        let stem = self
            .model
            .file_stem()
            .map_or_else(|| "pca".into(), |s| s.to_string_lossy().into_owned());
        match &self.point {
            PcaPoint::Mean => format!("{stem} mean"),
            PcaPoint::Coordinates(x) => format!("{stem} point ({} coordinates)", x.len()),
            PcaPoint::Material { name, k } | PcaPoint::Projection { spec: name, k } => match k {
                Some(k) => format!("{name} (PCA {k})"),
                None => format!("{name} (PCA)"),
            },
        }
    }
}

/// The resolver of `pca:` specs. It keeps the last model it loaded (models are large), reloading
/// when another file is named or the file changed.
#[derive(Default)]
pub struct PcaSpecs {
    last: Mutex<Option<CachedModel>>,
}

/// A model file's path, modification time and content.
type CachedModel = (PathBuf, Option<std::time::SystemTime>, Arc<Model>);

impl std::fmt::Debug for PcaSpecs {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str("PcaSpecs")
    }
}

impl PcaSpecs {
    /// The model stored in `path` (cached).
    pub fn model(&self, path: &Path) -> Result<Arc<Model>> {
        let modified = std::fs::metadata(path).and_then(|m| m.modified()).ok();
        let mut last = self.last.lock().unwrap_or_else(|e| e.into_inner());
        if let Some((p, t, m)) = last.as_ref() {
            if p == path && *t == modified && modified.is_some() {
                return Ok(m.clone());
            }
        }
        let m = Arc::new(Model::load(path)?);
        *last = Some((path.to_path_buf(), modified, m.clone()));
        Ok(m)
    }
}

impl SpecResolver for PcaSpecs {
    fn prefix(&self) -> &str {
        SPEC_PREFIX
    }

    fn form(&self) -> &str {
        "pca:<model.bin>[?c=<x1>/<x2>/…|?material=<name>[&k=<K>]|?of=<spec>[&k=<K>]]"
    }

    fn load(&self, spec: &str, rest: &str) -> brdf::Result<Material> {
        let wrap = |e: ReduceError| match e {
            ReduceError::Brdf(b) => b,
            other => brdf::resolver_error(spec, other),
        };
        let parsed = PcaSpec::parse(rest).map_err(wrap)?;
        let model = self.model(&parsed.model).map_err(wrap)?;
        Ok(Material::Table(parsed.table(&model).map_err(wrap)?))
    }
}

/// Registers [`PcaSpecs`] so that every material spec accepts the `pca:` forms (idempotent).
pub fn register_spec_resolver() {
    brdf::register(Arc::new(PcaSpecs::default())).expect("`pca` is a valid, free prefix");
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn parse_rejects_malformed_specs() {
        for s in [
            "",
            "?c=1",
            "m.bin?c=1&c=2",
            "m.bin?c=x",
            "m.bin?c=nan",
            "m.bin?k=3",
            "m.bin?c=1&k=3",
            "m.bin?material=",
            "m.bin?of=",
            "m.bin?k=0&of=merl:chrome",
            "m.bin?k=-1&of=merl:chrome",
            "m.bin?colour=red",
            "m.bin?c",
        ] {
            assert!(PcaSpec::parse(s).is_err(), "{s}");
        }
        assert_eq!(PcaSpec::parse(" m.bin ").unwrap().point, PcaPoint::Mean);
        assert_eq!(
            PcaSpec::parse("m.bin?material=chrome&k=4").unwrap().point,
            PcaPoint::Material {
                name: "chrome".into(),
                k: Some(4)
            }
        );
        // an analytic spec keeps its commas and equals signs
        assert_eq!(
            PcaSpec::parse("m.bin?k=2&of=ggx:alpha=0.2,kd=0.1")
                .unwrap()
                .point,
            PcaPoint::Projection {
                spec: "ggx:alpha=0.2,kd=0.1".into(),
                k: Some(2)
            }
        );
    }
}
