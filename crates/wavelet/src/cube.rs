//! Cubic arrays of side 2^L that hold a tabulated isotropic BRDF channel.

use crate::error::{Result, WaveletError};
use brdf::{PHI_D_RES, THETA_D_RES, THETA_H_RES};

/// Extent (θh, θd, φd) of a MERL table channel.
pub const MERL_EXTENT: [usize; 3] = [THETA_H_RES, THETA_D_RES, PHI_D_RES];

/// Side of the zero-padded cube that holds a MERL table channel (thesis §6.2).
pub const MERL_CUBE_SIDE: usize = 256;

/// A cube of `side³` single-precision values, `side` a power of two, holding a tabulated
/// isotropic BRDF channel.
///
/// A MERL table channel is a 90 (θh) × 90 (θd) × 180 (φd) array. Following thesis §6.2 it is
/// inserted at the origin of a 256³ cube and the rest of the cube is zero. Axis 0 of the cube is
/// θh, axis 1 is θd and axis 2 is φd; the flat index of `(x, y, z)` is `(x · side + y) · side + z`,
/// so that a MERL bin `φd + 180 · (θd + 90 · θh)` keeps its axis order.
///
/// # Examples
///
/// ```
/// use wavelet::Cube;
///
/// // a 2 × 2 × 4 table placed at the origin of an 8³ cube and taken out again
/// let table: Vec<f32> = (0..16).map(|i| i as f32).collect();
/// let cube = Cube::embed(&table, [2, 2, 4], 8).unwrap();
/// assert_eq!(cube.data()[cube.index(1, 1, 3)], 15.0);
/// assert_eq!(cube.data()[cube.index(7, 7, 7)], 0.0);
/// assert_eq!(cube.extract([2, 2, 4]).unwrap(), table);
/// assert!(Cube::zeros(12).is_err()); // not a power of two
/// ```
#[derive(Debug, Clone, PartialEq)]
pub struct Cube {
    side: usize,
    data: Vec<f32>,
}

/// Checks that `side` is a power of two of at least 2.
pub fn check_side(side: usize) -> Result<()> {
    if side < 2 || !side.is_power_of_two() {
        return Err(WaveletError::NotPowerOfTwo(side));
    }
    Ok(())
}

/// Index of the first non-finite value, if any.
pub(crate) fn first_non_finite(values: &[f32]) -> Option<usize> {
    values.iter().position(|v| !v.is_finite())
}

impl Cube {
    /// A cube of zeros.
    pub fn zeros(side: usize) -> Result<Self> {
        check_side(side)?;
        Ok(Self {
            side,
            data: vec![0.0; side * side * side],
        })
    }

    /// A cube from `side³` values in flat order; rejects NaN and infinities.
    pub fn from_vec(side: usize, data: Vec<f32>) -> Result<Self> {
        check_side(side)?;
        let expected = side * side * side;
        if data.len() != expected {
            return Err(WaveletError::Length {
                expected,
                found: data.len(),
            });
        }
        if let Some(index) = first_non_finite(&data) {
            return Err(WaveletError::NonFinite { index });
        }
        Ok(Self { side, data })
    }

    /// Inserts a table of the given extent (row-major, axis 2 fastest) at the origin of a
    /// zero cube of side `side`.
    pub fn embed(values: &[f32], extent: [usize; 3], side: usize) -> Result<Self> {
        check_side(side)?;
        if extent.iter().any(|&e| e > side) {
            return Err(WaveletError::ExtentTooLarge { extent, side });
        }
        let expected = extent[0] * extent[1] * extent[2];
        if values.len() != expected {
            return Err(WaveletError::Length {
                expected,
                found: values.len(),
            });
        }
        if let Some(index) = first_non_finite(values) {
            return Err(WaveletError::NonFinite { index });
        }
        let mut cube = Self::zeros(side)?;
        let [ex, ey, ez] = extent;
        for x in 0..ex {
            for y in 0..ey {
                let src = &values[(x * ey + y) * ez..][..ez];
                let dst = (x * side + y) * side;
                cube.data[dst..dst + ez].copy_from_slice(src);
            }
        }
        Ok(cube)
    }

    /// Inserts one MERL table channel (90 × 90 × 180 values in bin order) into a 256³ cube.
    pub fn embed_merl(values: &[f32]) -> Result<Self> {
        Self::embed(values, MERL_EXTENT, MERL_CUBE_SIDE)
    }

    /// The values of the region `[0, extent)` at the origin, row-major.
    pub fn extract(&self, extent: [usize; 3]) -> Result<Vec<f32>> {
        if extent.iter().any(|&e| e > self.side) {
            return Err(WaveletError::ExtentTooLarge {
                extent,
                side: self.side,
            });
        }
        let [ex, ey, ez] = extent;
        let mut out = Vec::with_capacity(ex * ey * ez);
        for x in 0..ex {
            for y in 0..ey {
                let src = (x * self.side + y) * self.side;
                out.extend_from_slice(&self.data[src..src + ez]);
            }
        }
        Ok(out)
    }

    /// The MERL region (90 × 90 × 180, bin order) of a cube of side at least 180.
    pub fn extract_merl(&self) -> Result<Vec<f32>> {
        self.extract(MERL_EXTENT)
    }

    /// Side of the cube.
    pub fn side(&self) -> usize {
        self.side
    }

    /// Number of levels of a full decomposition, log2(side).
    pub fn max_levels(&self) -> u32 {
        self.side.trailing_zeros()
    }

    /// Flat index of `(x, y, z)`.
    #[inline]
    pub fn index(&self, x: usize, y: usize, z: usize) -> usize {
        (x * self.side + y) * self.side + z
    }

    /// `(x, y, z)` of a flat index.
    #[inline]
    pub fn coords(&self, index: usize) -> [usize; 3] {
        let z = index % self.side;
        let r = index / self.side;
        [r / self.side, r % self.side, z]
    }

    /// The values in flat order.
    pub fn data(&self) -> &[f32] {
        &self.data
    }

    /// Mutable values in flat order.
    pub fn data_mut(&mut self) -> &mut [f32] {
        &mut self.data
    }

    /// The values, consuming the cube.
    pub fn into_vec(self) -> Vec<f32> {
        self.data
    }

    /// Sum of squares (f64 accumulation).
    pub fn energy(&self) -> f64 {
        self.data.iter().map(|&v| (v as f64) * (v as f64)).sum()
    }
}
