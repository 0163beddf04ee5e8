//! Binary file of a sampling [`Model`] (the `--model model.bin` of the CLI).

use std::path::Path;

use crate::error::{Result, SamplingError};
use crate::grid::SampleGrid;
use crate::logpca::LogPcaModel;
use crate::methods::Model;
use crate::plan::write_atomic;
use crate::training::TrainingSet;
use crate::wavelet_pattern::WaveletPatternModel;

const MAGIC: &[u8; 8] = b"SMPLMODL";
const END: &[u8; 7] = b"ENDSMPL";
const VERSION: u32 = 2;

fn put_u32(out: &mut Vec<u8>, v: usize) {
    out.extend_from_slice(&(v as u32).to_le_bytes());
}

fn put_f32s(out: &mut Vec<u8>, v: &[f32]) {
    for x in v {
        out.extend_from_slice(&x.to_le_bytes());
    }
}

fn put_f64s(out: &mut Vec<u8>, v: &[f64]) {
    for x in v {
        out.extend_from_slice(&x.to_le_bytes());
    }
}

/// Serialises a model.
pub fn to_bytes(model: &Model) -> Vec<u8> {
    let mut out = Vec::new();
    out.extend_from_slice(MAGIC);
    out.extend_from_slice(&VERSION.to_le_bytes());
    let kind = match model {
        Model::LinComb(_) => 0u8,
        Model::LogPca(_) => 1,
        Model::Grid(_) => 2,
        Model::Wavelet(_) => 3,
    };
    out.push(kind);
    let g = model.grid();
    for s in [g.theta_h_step, g.theta_d_step, g.phi_d_step] {
        put_u32(&mut out, s);
    }
    match model {
        Model::LinComb(t) => {
            put_u32(&mut out, t.len());
            for n in &t.names {
                put_u32(&mut out, n.len());
                out.extend_from_slice(n.as_bytes());
            }
            put_f32s(&mut out, &t.values);
        }
        Model::LogPca(m) => {
            put_u32(&mut out, m.components);
            put_f64s(&mut out, &[m.noise_variance]);
            put_f64s(&mut out, &m.mean);
            put_f64s(&mut out, &m.basis);
            put_f64s(&mut out, &m.prior_variance);
            put_f64s(&mut out, &m.residual_variance);
        }
        Model::Grid(_) => {}
        Model::Wavelet(w) => {
            put_u32(&mut out, w.len());
            for &i in w.basis.indices() {
                out.extend_from_slice(&i.to_le_bytes());
            }
            for m in &w.mean_coefficients {
                put_f64s(&mut out, m);
            }
        }
    }
    out.extend_from_slice(END);
    out
}

/// Writes a model file atomically (the `--model model.bin` of the CLI; [`load`] reads it).
///
/// Layout, little-endian: magic `SMPLMODL`, `u32` version (2), `u8` kind (0 = linear
/// combination, 1 = log PCA, 2 = grid only, 3 = wavelet pattern), three `u32` grid strides (θh, θd, φd), then
/// * kind 0: `u32` N; N names (`u32` byte length + UTF-8); `N × 3G` `f32` values (≥ 0),
///   material-major (version 1 stored them as `f64`; it is no longer read);
/// * kind 1: `u32` k; `f64` noise variance; `3G` mean; `3G × k` basis (row-major);
///   `k` prior variances; `3G` residual variances (all `f64`);
/// * kind 2: nothing more;
/// * kind 3: `u32` count; count `u32` CWB cube indices; `3 × count` `f64` mean coefficients;
///
/// and the marker `ENDSMPL`. `G` is the number of grid points. Every size is checked against
/// the remaining bytes before allocation; values must be finite.
///
/// # Examples
///
/// ```
/// use sampling::{Model, SampleGrid};
///
/// let path = std::env::temp_dir().join(format!("sampling-doc-{}.bin", std::process::id()));
/// let grid = SampleGrid::new(9, 9, 18).unwrap();
/// sampling::save(&Model::Grid(grid), &path).unwrap();
/// let back = sampling::load(&path).unwrap();
/// # std::fs::remove_file(&path).unwrap();
/// assert!(matches!(back, Model::Grid(g) if g == grid));
/// ```
pub fn save(model: &Model, path: impl AsRef<Path>) -> Result<()> {
    write_atomic(path.as_ref(), &to_bytes(model))
}

/// Reads a model file written by [`save`] (whose docs give the layout and an example).
pub fn load(path: impl AsRef<Path>) -> Result<Model> {
    let path = path.as_ref();
    let bytes = std::fs::read(path).map_err(|e| SamplingError::io(path, e))?;
    from_bytes(&bytes).map_err(|e| match e {
        SamplingError::InvalidParameter(m) => {
            SamplingError::InvalidParameter(format!("{}: {m}", path.display()))
        }
        other => other,
    })
}

struct Reader<'a> {
    bytes: &'a [u8],
    pos: usize,
}

fn malformed(reason: impl Into<String>) -> SamplingError {
    SamplingError::InvalidParameter(format!("malformed model file: {}", reason.into()))
}

impl Reader<'_> {
    fn take(&mut self, n: usize) -> Result<&[u8]> {
        if self.bytes.len() - self.pos < n {
            return Err(malformed("truncated"));
        }
        let s = &self.bytes[self.pos..self.pos + n];
        self.pos += n;
        Ok(s)
    }
    fn u32(&mut self) -> Result<usize> {
        let b = self.take(4)?;
        Ok(u32::from_le_bytes([b[0], b[1], b[2], b[3]]) as usize)
    }
    fn f32s(&mut self, n: usize) -> Result<Vec<f32>> {
        let len = n.checked_mul(4).ok_or_else(|| malformed("size overflow"))?;
        let b = self.take(len)?;
        let v: Vec<f32> = b
            .chunks_exact(4)
            .map(|c| f32::from_le_bytes(c.try_into().expect("4 bytes")))
            .collect();
        if v.iter().any(|x| !x.is_finite()) {
            return Err(malformed("non-finite value"));
        }
        Ok(v)
    }
    fn f64s(&mut self, n: usize) -> Result<Vec<f64>> {
        let len = n.checked_mul(8).ok_or_else(|| malformed("size overflow"))?;
        let b = self.take(len)?;
        let v: Vec<f64> = b
            .chunks_exact(8)
            .map(|c| f64::from_le_bytes(c.try_into().expect("8 bytes")))
            .collect();
        if v.iter().any(|x| !x.is_finite()) {
            return Err(malformed("non-finite value"));
        }
        Ok(v)
    }
}

/// Parses a model file.
pub fn from_bytes(bytes: &[u8]) -> Result<Model> {
    let mut r = Reader { bytes, pos: 0 };
    if r.take(8)? != MAGIC {
        return Err(malformed("bad magic"));
    }
    if r.u32()? != VERSION as usize {
        return Err(malformed("unknown version"));
    }
    let kind = r.take(1)?[0];
    let grid =
        SampleGrid::new(r.u32()?, r.u32()?, r.u32()?).map_err(|_| malformed("zero grid stride"))?;
    if grid.theta_h_step > 90 || grid.theta_d_step > 90 || grid.phi_d_step > 180 {
        return Err(malformed("implausible grid stride"));
    }
    let d = 3 * grid.len();
    let model = match kind {
        0 => {
            let n = r.u32()?;
            if n == 0 || n > 100_000 {
                return Err(malformed("implausible material count"));
            }
            let mut names = Vec::with_capacity(n.min(1024));
            for _ in 0..n {
                let len = r.u32()?;
                let s = std::str::from_utf8(r.take(len)?).map_err(|_| malformed("name"))?;
                names.push(s.to_string());
            }
            let values = r.f32s(n.checked_mul(d).ok_or_else(|| malformed("size"))?)?;
            if values.iter().any(|v| *v < 0.0) {
                return Err(malformed("negative training value"));
            }
            Model::LinComb(TrainingSet {
                grid,
                names,
                values,
            })
        }
        1 => {
            let k = r.u32()?;
            if k == 0 || k > 100_000 {
                return Err(malformed("implausible component count"));
            }
            let noise_variance = r.f64s(1)?[0];
            let mean = r.f64s(d)?;
            let basis = r.f64s(d.checked_mul(k).ok_or_else(|| malformed("size"))?)?;
            let prior_variance = r.f64s(k)?;
            let residual_variance = r.f64s(d)?;
            if prior_variance.iter().any(|v| *v <= 0.0)
                || residual_variance.iter().any(|v| *v < 0.0)
                || noise_variance < 0.0
            {
                return Err(malformed("negative variance"));
            }
            Model::LogPca(LogPcaModel {
                grid,
                mean,
                basis,
                components: k,
                prior_variance,
                residual_variance,
                noise_variance,
            })
        }
        2 => Model::Grid(grid),
        3 => {
            let count = r.u32()?;
            let side = crate::wavelet_pattern::layout_of(&grid).side;
            if count == 0 || count > side * side * side {
                return Err(malformed("implausible basis size"));
            }
            let mut indices = Vec::with_capacity(count);
            for _ in 0..count {
                indices.push(r.u32()? as u32);
            }
            let mean = [r.f64s(count)?, r.f64s(count)?, r.f64s(count)?];
            Model::Wavelet(
                WaveletPatternModel::from_parts(grid, indices, mean)
                    .map_err(|e| malformed(e.to_string()))?,
            )
        }
        _ => return Err(malformed("unknown model kind")),
    };
    if r.take(END.len())? != END {
        return Err(malformed("missing end marker"));
    }
    if r.pos != bytes.len() {
        return Err(malformed("trailing bytes"));
    }
    Ok(model)
}
