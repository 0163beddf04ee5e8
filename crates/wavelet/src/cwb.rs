//! The Common Wavelet Basis (thesis §6.2).

use crate::basis::{keep_for_relative_error, CoefficientAddress};
use crate::cube::{Cube, MERL_CUBE_SIDE, MERL_EXTENT};
use crate::error::{Result, WaveletError};
use crate::transform::{self, Wavelet};
use rayon::prelude::*;

/// How one component fared when it was added to a basis.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ComponentStats {
    /// Coefficients kept to reach the error target.
    pub kept: usize,
    /// Relative L2 error of the component with only those coefficients (from Parseval; exact
    /// for orthonormal wavelets).
    pub relative_error: f64,
    /// Non-zero coefficients of the component's transform.
    pub nonzero: usize,
}

/// Geometry shared by bases and trees: the cube side, the table extent inside it and the filter.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Layout {
    /// Cube side (power of two).
    pub side: usize,
    /// Extent (θh, θd, φd) of the tabulated functions at the cube origin.
    pub extent: [usize; 3],
    /// The wavelet filter.
    pub wavelet: Wavelet,
}

impl Layout {
    /// The thesis's layout: 90 × 90 × 180 tables in a 256³ cube, Haar wavelets.
    pub const MERL_HAAR: Layout = Layout {
        side: MERL_CUBE_SIDE,
        extent: MERL_EXTENT,
        wavelet: Wavelet::Haar,
    };

    /// Checks the side (a power of two whose cube is addressable by the `u32` coefficient
    /// indices of a basis) and that the extent fits.
    pub fn validate(&self) -> Result<()> {
        crate::cube::check_side(self.side)?;
        if self
            .side
            .checked_pow(3)
            .is_none_or(|n| n > u32::MAX as usize + 1)
        {
            return Err(WaveletError::Format(format!(
                "cube side {} too large: its coefficients do not fit u32 indices",
                self.side
            )));
        }
        if self.extent.iter().any(|&e| e > self.side || e == 0) {
            return Err(WaveletError::ExtentTooLarge {
                extent: self.extent,
                side: self.side,
            });
        }
        Ok(())
    }

    /// Number of values of one tabulated function.
    pub fn table_len(&self) -> usize {
        self.extent.iter().product()
    }

    /// Number of coefficients of the cube.
    pub fn cube_len(&self) -> usize {
        self.side * self.side * self.side
    }

    /// Full forward transform of a tabulated function (zero-padded into the cube).
    pub fn analyse(&self, values: &[f32]) -> Result<Cube> {
        let mut cube = Cube::embed(values, self.extent, self.side)?;
        transform::forward_full(&mut cube, self.wavelet)?;
        Ok(cube)
    }

    /// Full inverse transform of a coefficient cube, returning the tabulated region.
    pub fn synthesise(&self, mut coefficients: Cube) -> Result<Vec<f32>> {
        if coefficients.side() != self.side {
            return Err(WaveletError::SideMismatch(coefficients.side(), self.side));
        }
        transform::inverse_full(&mut coefficients, self.wavelet)?;
        coefficients.extract(self.extent)
    }
}

/// Accumulates the Common Wavelet Basis one component (or one batch) at a time, so that a large
/// corpus never has to be held in memory at once.
#[derive(Debug, Clone)]
pub struct CommonBasisBuilder {
    layout: Layout,
    target: f64,
    member: Vec<u64>,
    stats: Vec<ComponentStats>,
}

impl CommonBasisBuilder {
    /// A builder for the given layout and relative-error target (e.g. 0.03).
    pub fn new(layout: Layout, target: f64) -> Result<Self> {
        layout.validate()?;
        if !(0.0..=1.0).contains(&target) {
            return Err(WaveletError::BadErrorTarget(target));
        }
        Ok(Self {
            layout,
            target,
            member: vec![0; layout.cube_len().div_ceil(64)],
            stats: Vec::new(),
        })
    }

    /// Thresholds one component (a tabulated function of the layout's extent) and adds its
    /// kept coefficients to the basis.
    pub fn add(&mut self, component: &[f32]) -> Result<ComponentStats> {
        let (kept, stats) = self.threshold(component)?;
        self.insert(&kept, stats);
        Ok(stats)
    }

    /// Adds several components, transforming them in parallel.
    pub fn add_many(&mut self, components: &[&[f32]]) -> Result<Vec<ComponentStats>> {
        let results: Vec<Result<(Vec<u32>, ComponentStats)>> =
            components.par_iter().map(|c| self.threshold(c)).collect();
        let mut out = Vec::with_capacity(results.len());
        for r in results {
            let (kept, stats) = r?;
            self.insert(&kept, stats);
            out.push(stats);
        }
        Ok(out)
    }

    fn threshold(&self, component: &[f32]) -> Result<(Vec<u32>, ComponentStats)> {
        let cube = self.layout.analyse(component)?;
        let t = keep_for_relative_error(cube.data(), self.target)?;
        tracing::debug!(
            kept = t.indices.len(),
            err = t.relative_error,
            "component thresholded"
        );
        let stats = ComponentStats {
            kept: t.indices.len(),
            relative_error: t.relative_error,
            nonzero: t.nonzero,
        };
        Ok((t.indices, stats))
    }

    fn insert(&mut self, kept: &[u32], stats: ComponentStats) {
        for &i in kept {
            self.member[i as usize / 64] |= 1u64 << (i % 64);
        }
        self.stats.push(stats);
    }

    /// Statistics of the components added so far, in order.
    pub fn stats(&self) -> &[ComponentStats] {
        &self.stats
    }

    /// The basis: the union of all kept coefficients.
    pub fn finish(self) -> CommonBasis {
        let mut indices = Vec::new();
        for (w, &bits) in self.member.iter().enumerate() {
            let mut b = bits;
            while b != 0 {
                let t = b.trailing_zeros();
                indices.push((w * 64) as u32 + t);
                b &= b - 1;
            }
        }
        CommonBasis {
            layout: self.layout,
            indices,
        }
    }
}

/// A set of wavelet coefficient positions shared by a family of functions: the Common Wavelet
/// Basis of thesis §6.2.
///
/// Each component of a corpus (a BRDF colour channel, a PCA component, …) is transformed and
/// thresholded to a relative-error target (3 % in the thesis); the Common Wavelet Basis (CWB) is the
/// union of the kept coefficient positions over all components. Any function of the corpus, and
/// hopefully any similar one, is then represented by its coefficients on the CWB alone.
///
/// # Examples
///
/// ```
/// use wavelet::{CommonBasis, Layout, Wavelet};
///
/// // the Common Wavelet Basis of two functions on a 4 × 4 × 8 table, at 1 % relative error
/// let layout = Layout { side: 16, extent: [4, 4, 8], wavelet: Wavelet::Haar };
/// let f: Vec<f32> = (0..128).map(|i| (i as f32 * 0.1).cos()).collect();
/// let g: Vec<f32> = (0..128).map(|i| 1.0 + (i / 32) as f32).collect();
/// let (basis, stats) = CommonBasis::build(layout, &[&f, &g], 0.01).unwrap();
/// assert!(stats.iter().all(|s| s.relative_error <= 0.01));
/// let coefficients = basis.coefficients(&f).unwrap();
/// assert_eq!(coefficients.len(), basis.len());
/// ```
#[derive(Debug, Clone, PartialEq)]
pub struct CommonBasis {
    layout: Layout,
    indices: Vec<u32>,
}

impl CommonBasis {
    /// Builds the basis of `components` at relative-error target `target` (seed: 0.03),
    /// returning it with per-component statistics.
    pub fn build(
        layout: Layout,
        components: &[&[f32]],
        target: f64,
    ) -> Result<(Self, Vec<ComponentStats>)> {
        let mut b = CommonBasisBuilder::new(layout, target)?;
        let stats = b.add_many(components)?;
        Ok((b.finish(), stats))
    }

    /// A basis from explicit flat coefficient indices (sorted and deduplicated here).
    pub fn from_indices(layout: Layout, mut indices: Vec<u32>) -> Result<Self> {
        layout.validate()?;
        let len = layout.cube_len();
        if let Some(&bad) = indices.iter().find(|&&i| i as usize >= len) {
            return Err(WaveletError::IndexOutOfRange {
                index: bad as usize,
                len,
            });
        }
        indices.sort_unstable();
        indices.dedup();
        Ok(Self { layout, indices })
    }

    /// The layout the basis was built for.
    pub fn layout(&self) -> Layout {
        self.layout
    }

    /// Flat cube indices of the basis functions, increasing.
    pub fn indices(&self) -> &[u32] {
        &self.indices
    }

    /// Number of basis functions.
    pub fn len(&self) -> usize {
        self.indices.len()
    }

    /// Whether the basis is empty.
    pub fn is_empty(&self) -> bool {
        self.indices.is_empty()
    }

    /// Size relative to the number of table values (seed: about 69,000 = 4.7 % of 1.458 M).
    pub fn fraction_of_table(&self) -> f64 {
        self.indices.len() as f64 / self.layout.table_len() as f64
    }

    /// Address (level, type, offset) of basis function `i`.
    pub fn address(&self, i: usize) -> CoefficientAddress {
        let side = self.layout.side;
        let c = self.indices[i] as usize;
        CoefficientAddress::from_coords([c / (side * side), (c / side) % side, c % side])
    }

    /// Number of basis functions per level (index = level, 0 coarsest; the scaling function
    /// counts at level 0).
    pub fn level_histogram(&self) -> Vec<usize> {
        let mut h = vec![0; self.layout.side.trailing_zeros() as usize];
        for i in 0..self.indices.len() {
            h[self.address(i).level as usize] += 1;
        }
        h
    }

    /// Coefficients of a tabulated function on the basis (its transform sampled at the basis
    /// positions).
    pub fn coefficients(&self, values: &[f32]) -> Result<Vec<f32>> {
        let cube = self.layout.analyse(values)?;
        let d = cube.data();
        Ok(self.indices.iter().map(|&i| d[i as usize]).collect())
    }

    /// The tabulated function whose transform is `coefficients` on the basis and zero elsewhere.
    pub fn reconstruct(&self, coefficients: &[f32]) -> Result<Vec<f32>> {
        if coefficients.len() != self.indices.len() {
            return Err(WaveletError::Length {
                expected: self.indices.len(),
                found: coefficients.len(),
            });
        }
        if let Some(index) = crate::cube::first_non_finite(coefficients) {
            return Err(WaveletError::NonFinite { index });
        }
        let mut cube = Cube::zeros(self.layout.side)?;
        let d = cube.data_mut();
        for (&i, &c) in self.indices.iter().zip(coefficients) {
            d[i as usize] = c;
        }
        self.layout.synthesise(cube)
    }

    /// Projection of a tabulated function onto the basis ("CWB alone" representation).
    pub fn project(&self, values: &[f32]) -> Result<Vec<f32>> {
        let c = self.coefficients(values)?;
        self.reconstruct(&c)
    }
}

/// Magic bytes of the basis file format written by [`CommonBasis::write`].
pub const BASIS_MAGIC: &[u8; 8] = b"CWBASIS1";

impl CommonBasis {
    /// Serialises the basis: magic, side (u32), extent (3 × u32), wavelet (u8: 0 Haar,
    /// 1 CDF 5/3, 2 Daubechies-4), count (u64), then the flat indices (u32), little-endian.
    pub fn to_bytes(&self) -> Vec<u8> {
        let mut b = Vec::with_capacity(8 + 4 * 4 + 1 + 8 + 4 * self.indices.len());
        b.extend_from_slice(BASIS_MAGIC);
        b.extend_from_slice(&(self.layout.side as u32).to_le_bytes());
        for e in self.layout.extent {
            b.extend_from_slice(&(e as u32).to_le_bytes());
        }
        b.push(match self.layout.wavelet {
            Wavelet::Haar => 0,
            Wavelet::Cdf53 => 1,
            Wavelet::Daub4 => 2,
        });
        b.extend_from_slice(&(self.indices.len() as u64).to_le_bytes());
        for i in &self.indices {
            b.extend_from_slice(&i.to_le_bytes());
        }
        b
    }

    /// Parses the format of [`Self::to_bytes`].
    pub fn from_bytes(bytes: &[u8]) -> Result<Self> {
        let bad = |what: &str| WaveletError::Format(what.to_string());
        let header = 8 + 16 + 1 + 8;
        if bytes.len() < header || &bytes[..8] != BASIS_MAGIC {
            return Err(bad("missing CWBASIS1 header"));
        }
        let u32_at =
            |o: usize| u32::from_le_bytes([bytes[o], bytes[o + 1], bytes[o + 2], bytes[o + 3]]);
        let side = u32_at(8) as usize;
        let extent = [
            u32_at(12) as usize,
            u32_at(16) as usize,
            u32_at(20) as usize,
        ];
        let wavelet = match bytes[24] {
            0 => Wavelet::Haar,
            1 => Wavelet::Cdf53,
            2 => Wavelet::Daub4,
            _ => return Err(bad("unknown wavelet code")),
        };
        let mut n = [0u8; 8];
        n.copy_from_slice(&bytes[25..33]);
        let count = u64::from_le_bytes(n) as usize;
        if bytes.len() - header != count.checked_mul(4).ok_or_else(|| bad("count overflow"))? {
            return Err(bad("index count does not match file length"));
        }
        let indices = bytes[header..]
            .chunks_exact(4)
            .map(|c| u32::from_le_bytes([c[0], c[1], c[2], c[3]]))
            .collect();
        let layout = Layout {
            side,
            extent,
            wavelet,
        };
        Self::from_indices(layout, indices)
    }

    /// Writes the basis atomically (temporary file in the same directory, then rename).
    pub fn write(&self, path: impl AsRef<std::path::Path>) -> Result<()> {
        let path = path.as_ref();
        brdf::write_atomic(path, &self.to_bytes()).map_err(|e| WaveletError::Io(e.to_string()))
    }

    /// Reads a basis written by [`Self::write`].
    pub fn read(path: impl AsRef<std::path::Path>) -> Result<Self> {
        let path = path.as_ref();
        let bytes = std::fs::read(path)
            .map_err(|e| WaveletError::Io(format!("{}: {e}", path.display())))?;
        Self::from_bytes(&bytes)
    }
}

/// Splits a dimension-major matrix of `count` stacked vectors (`matrix[d · count + k]` = entry
/// `d` of vector `k`, the layout of `reduce`'s PCA basis) into its vectors, each cut into
/// consecutive functions of `function_len` values (e.g. the R, G, B tables of a component).
///
/// Returns `count · (dim / function_len)` functions, vector-major.
pub fn functions_from_dimension_major(
    matrix: &[f32],
    count: usize,
    function_len: usize,
) -> Result<Vec<Vec<f32>>> {
    if count == 0 {
        return Err(WaveletError::NoFunctions);
    }
    if function_len == 0 || matrix.len() % (count * function_len) != 0 {
        return Err(WaveletError::Length {
            expected: count * function_len.max(1),
            found: matrix.len(),
        });
    }
    let dim = matrix.len() / count;
    let per = dim / function_len;
    let mut out = Vec::with_capacity(count * per);
    for k in 0..count {
        for f in 0..per {
            out.push(
                (0..function_len)
                    .map(|i| matrix[(f * function_len + i) * count + k])
                    .collect(),
            );
        }
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_basis_file_with_a_huge_cube_side_is_refused_not_overflowed() {
        // Found by the wavelet_basis fuzz target: side 2^22 made cube_len overflow.
        let mut bytes = BASIS_MAGIC.to_vec();
        for v in [1u32 << 22, 251, 1 << 22, 0x21] {
            bytes.extend_from_slice(&v.to_le_bytes());
        }
        bytes.push(0);
        bytes.extend_from_slice(&0u64.to_le_bytes());
        let err = CommonBasis::from_bytes(&bytes).unwrap_err();
        assert!(err.to_string().contains("too large"), "{err}");
        // A large side that is addressable still validates.
        let ok = Layout {
            side: 1 << 10,
            extent: [90, 90, 180],
            wavelet: Wavelet::Haar,
        };
        assert!(ok.validate().is_ok());
    }
}
