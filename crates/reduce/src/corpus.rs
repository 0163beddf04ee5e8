//! A corpus of measured materials as log-space vectors (seed §4.1).
//!
//! Every material is one vector of `D = 3 × 1,458,000` values: the full MERL table, channel
//! major (R bins, then G, then B), all bins kept. Each BRDF value `f` (1/sr) becomes
//! `ln(max(f, 0) + LOG_FLOOR)`: the floor keeps zeros and missing bins (negative values in a
//! `.binary` file, treated as 0) finite and limits the weight of the darkest, noisiest values;
//! it is added rather than clamped so the transform is exactly invertible for valid values
//! (`f = exp(y) − LOG_FLOOR`). Vectors are stored as `f32`, material-major, in one contiguous
//! buffer: 96 materials take 1.68 GB.

use std::path::{Path, PathBuf};

use brdf::table::BINS;

use crate::error::{ReduceError, Result};

/// Floor added to BRDF values (1/sr) before taking the natural logarithm. `10⁻³ sr⁻¹` is about
/// the value of a Lambertian surface with albedo 0.3 %, darker than any material of the corpus
/// at normal incidence.
pub const LOG_FLOOR: f64 = 1e-3;

/// Length of one material vector (all bins of the three channels).
pub const MATERIAL_DIM: usize = 3 * BINS;

/// Log-space value of a BRDF value (negative = missing is treated as 0).
#[inline]
pub fn to_log(value: f64) -> f32 {
    (value.max(0.0) + LOG_FLOOR).ln() as f32
}

/// BRDF value of a log-space value; negative when `y < ln(LOG_FLOOR)` (a linear model can
/// produce those: they are physically invalid).
#[inline]
pub fn from_log(y: f32) -> f64 {
    (y as f64).exp() - LOG_FLOOR
}

/// Converts BRDF values to a log-space vector, rejecting NaN and infinities.
pub fn log_vector(values: &[f64]) -> Result<Vec<f32>> {
    if values.iter().any(|v| !v.is_finite()) {
        return Err(ReduceError::NonFinite("BRDF values"));
    }
    Ok(values.iter().map(|&v| to_log(v)).collect())
}

/// Converts a log-space vector back to BRDF values, clamping invalid (negative) values to 0.
pub fn values_from_log(y: &[f32]) -> Vec<f64> {
    y.iter().map(|&v| from_log(v).max(0.0)).collect()
}

/// Named materials as log-space vectors of equal length.
#[derive(Debug, Clone, Default)]
pub struct Corpus {
    names: Vec<String>,
    dim: usize,
    data: Vec<f32>,
}

impl Corpus {
    /// An empty corpus of vectors of length `dim`.
    pub fn new(dim: usize) -> Corpus {
        Corpus {
            names: Vec::new(),
            dim,
            data: Vec::new(),
        }
    }

    /// Appends a material given by its BRDF values (1/sr; negative = missing).
    pub fn push_values(&mut self, name: impl Into<String>, values: &[f64]) -> Result<()> {
        self.check_len(values.len())?;
        let y = log_vector(values)?;
        self.data.extend_from_slice(&y);
        self.names.push(name.into());
        Ok(())
    }

    /// Appends a material given by single-precision BRDF values, converted in place to log space.
    pub fn push_values_f32(&mut self, name: impl Into<String>, mut values: Vec<f32>) -> Result<()> {
        self.check_len(values.len())?;
        if values.iter().any(|v| !v.is_finite()) {
            return Err(ReduceError::NonFinite("BRDF values"));
        }
        for v in values.iter_mut() {
            *v = to_log(*v as f64);
        }
        if self.data.is_empty() {
            self.data = values;
        } else {
            self.data.extend_from_slice(&values);
        }
        self.names.push(name.into());
        Ok(())
    }

    fn check_len(&self, len: usize) -> Result<()> {
        if len != self.dim {
            return Err(ReduceError::Dimension {
                what: "material vector length",
                expected: self.dim,
                got: len,
            });
        }
        Ok(())
    }

    /// Loads every complete material of an NBRDF weight directory (sorted by name), decoding
    /// each on the MERL grid with the `f32` fast path.
    pub fn from_nbrdf_dir(dir: impl AsRef<Path>) -> Result<Corpus> {
        let mut c = Corpus::new(MATERIAL_DIM);
        c.add_nbrdf_dir(dir.as_ref())?;
        Ok(c)
    }

    fn add_nbrdf_dir(&mut self, dir: &Path) -> Result<usize> {
        let names = brdf::nbrdf::list(dir)?;
        self.data.reserve(names.len() * MATERIAL_DIM);
        for name in &names {
            let net = brdf::nbrdf::Nbrdf::load(dir, name)?;
            self.push_values_f32(name.clone(), net.tabulate_f32())?;
            tracing::debug!(material = %name, "corpus: decoded NBRDF");
        }
        Ok(names.len())
    }

    /// Loads MERL `.binary` files (material name = file stem).
    pub fn from_binary_files(paths: &[PathBuf]) -> Result<Corpus> {
        let mut c = Corpus::new(MATERIAL_DIM);
        for p in paths {
            c.add_binary(p)?;
        }
        Ok(c)
    }

    fn add_binary(&mut self, p: &Path) -> Result<()> {
        let table = brdf::merl::read(p)?;
        let name = p.file_stem().map_or_else(
            || p.display().to_string(),
            |s| s.to_string_lossy().into_owned(),
        );
        self.push_values(name, &table.values())
    }

    /// Loads a corpus from a mix of inputs: directories (all NBRDF materials and all `.binary`
    /// files in them) and `.binary` files.
    pub fn load(inputs: &[PathBuf]) -> Result<Corpus> {
        let mut c = Corpus::new(MATERIAL_DIM);
        for input in inputs {
            if input.is_dir() {
                let found = c.add_nbrdf_dir(input)?;
                let mut bins: Vec<PathBuf> = std::fs::read_dir(input)
                    .map_err(|e| ReduceError::io(input, e))?
                    .filter_map(|e| e.ok().map(|e| e.path()))
                    .filter(|p| p.extension().is_some_and(|x| x == "binary"))
                    .collect();
                bins.sort();
                for b in &bins {
                    c.add_binary(b)?;
                }
                if found + bins.len() == 0 {
                    return Err(ReduceError::NotEnoughData(format!(
                        "{}: no NBRDF materials or .binary files",
                        input.display()
                    )));
                }
            } else {
                c.add_binary(input)?;
            }
        }
        Ok(c)
    }

    /// Number of materials.
    pub fn len(&self) -> usize {
        self.names.len()
    }

    /// Whether the corpus is empty.
    pub fn is_empty(&self) -> bool {
        self.names.is_empty()
    }

    /// Vector length `D`.
    pub fn dim(&self) -> usize {
        self.dim
    }

    /// Material names, in row order.
    pub fn names(&self) -> &[String] {
        &self.names
    }

    /// All vectors, row-major `N × D`.
    pub fn data(&self) -> &[f32] {
        &self.data
    }

    /// The log-space vector of material `i`.
    pub fn row(&self, i: usize) -> &[f32] {
        &self.data[i * self.dim..(i + 1) * self.dim]
    }

    /// Takes the buffer out (e.g. to convert it to linear values for NMF without a copy).
    pub fn into_parts(self) -> (Vec<String>, usize, Vec<f32>) {
        (self.names, self.dim, self.data)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn log_transform_round_trips_valid_values_and_floors_missing_ones() {
        for v in [0.0, 1e-4, 0.3, 17.0, 3000.0] {
            let back = from_log(to_log(v));
            assert!((back - v).abs() <= 1e-6 * (v + LOG_FLOOR), "{v} -> {back}");
        }
        assert_eq!(to_log(-1.0), to_log(0.0));
        assert!(
            from_log(to_log(0.0) - 0.5) < 0.0,
            "below the floor maps to negative BRDF"
        );
        assert!(log_vector(&[1.0, f64::NAN]).is_err());
    }

    #[test]
    fn corpus_checks_lengths() {
        let mut c = Corpus::new(4);
        c.push_values("a", &[0.1, 0.2, 0.3, -1.0]).unwrap();
        c.push_values_f32("b", vec![1.0, 2.0, 3.0, 4.0]).unwrap();
        assert!(c.push_values("c", &[1.0]).is_err());
        assert!(c.push_values_f32("d", vec![f32::INFINITY; 4]).is_err());
        assert_eq!(c.len(), 2);
        assert_eq!(c.row(1)[1], to_log(2.0));
        assert_eq!(c.names(), ["a", "b"]);
    }
}
