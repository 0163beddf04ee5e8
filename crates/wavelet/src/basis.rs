//! Haar coefficient addressing, basis functions (6.3)–(6.4) and thresholding.

use crate::error::{Result, WaveletError};

/// Where a coefficient sits in the nonstandard decomposition, and the Haar basis function
/// (thesis eqs. 6.3–6.4) it multiplies.
///
/// In the in-place layout of [`Wavelet`](crate::Wavelet) on a cube of side `n = 2^L`, the coefficient
/// stored at `(x, y, z)` is
///
/// * the scaling coefficient Γ⁰ when `x = y = z = 0`;
/// * otherwise the wavelet Γᵐ of level `l = ⌊log2 max(x, y, z)⌋` (0 = coarsest), whose type
///   `m ∈ 1..=7` has bit 2 set when `x ≥ 2^l` (ψ along θh), bit 1 when `y ≥ 2^l` (ψ along θd) and
///   bit 0 when `z ≥ 2^l` (ψ along φd), exactly the numbering of (6.4); its offset is
///   `(x mod 2^l, y mod 2^l, z mod 2^l)` where the modulo only applies along ψ axes (the other
///   coordinates are already below `2^l`).
///
/// A level-`l` function is supported on a block of `w = n / 2^l` cells per axis starting at
/// `offset · w`. The orthonormal Haar φ is `1/√w` on the block; ψ is `+1/√w` on its first half
/// and `−1/√w` on the second.
///
/// # Examples
///
/// ```
/// use wavelet::CoefficientAddress;
///
/// // in a 16³ cube, (5, 1, 2) is a level-2 wavelet, ψ along θh only, at offset (1, 1, 2)
/// let a = CoefficientAddress::from_coords([5, 1, 2]);
/// assert_eq!((a.level, a.kind, a.offset), (2, 0b100, [1, 1, 2]));
/// assert_eq!(a.to_coords(), [5, 1, 2]);
/// // its support is the 4³ block at (4, 4, 8); +1/√4³ on the first half along θh
/// assert_eq!(a.haar_value(16, [4, 4, 8]), 0.125);
/// assert_eq!(a.haar_value(16, [6, 4, 8]), -0.125);
/// assert_eq!(a.haar_value(16, [0, 0, 0]), 0.0);
/// ```
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub struct CoefficientAddress {
    /// Scale level, 0 = coarsest (the root of the coefficient tree).
    pub level: u32,
    /// Basis type: 0 = scaling function Γ⁰, 1..=7 = wavelet Γᵐ of (6.4).
    pub kind: u8,
    /// Offset (i, j, k) of the node at this level, each in `[0, 2^level)`.
    pub offset: [u32; 3],
}

impl CoefficientAddress {
    /// Address of the coefficient stored at `(x, y, z)` of a transformed cube.
    pub fn from_coords(coords: [usize; 3]) -> Self {
        let m = coords[0].max(coords[1]).max(coords[2]);
        if m == 0 {
            return Self {
                level: 0,
                kind: 0,
                offset: [0; 3],
            };
        }
        let level = usize::BITS - 1 - m.leading_zeros();
        let half = 1usize << level;
        let mut kind = 0u8;
        let mut offset = [0u32; 3];
        for a in 0..3 {
            let c = coords[a];
            if c >= half {
                kind |= 1 << (2 - a);
                offset[a] = (c - half) as u32;
            } else {
                offset[a] = c as u32;
            }
        }
        Self {
            level,
            kind,
            offset,
        }
    }

    /// Position `(x, y, z)` of this coefficient in a transformed cube.
    pub fn to_coords(&self) -> [usize; 3] {
        if self.kind == 0 {
            return [0; 3];
        }
        let half = 1usize << self.level;
        let mut c = [0usize; 3];
        for (a, ca) in c.iter_mut().enumerate() {
            *ca = self.offset[a] as usize
                + if self.kind & (1 << (2 - a)) != 0 {
                    half
                } else {
                    0
                };
        }
        c
    }

    /// Whether the basis function is ψ (rather than φ) along axis `a` (0 = θh, 1 = θd, 2 = φd).
    #[inline]
    pub fn is_wavelet_along(&self, a: usize) -> bool {
        self.kind & (1 << (2 - a)) != 0
    }

    /// Inclusive-exclusive cell ranges `[start, end)` per axis of the support of this basis
    /// function in a cube of side `side`.
    pub fn support(&self, side: usize) -> [std::ops::Range<usize>; 3] {
        let w = side >> self.level;
        let r = |a: usize| {
            let s = self.offset[a] as usize * w;
            s..s + w
        };
        [r(0), r(1), r(2)]
    }

    /// Value of the orthonormal Haar basis function at cell `cell` of a cube of side `side`.
    pub fn haar_value(&self, side: usize, cell: [usize; 3]) -> f64 {
        let w = side >> self.level;
        let mut sign = 1.0;
        for (a, &c) in cell.iter().enumerate() {
            let start = self.offset[a] as usize * w;
            if c < start || c >= start + w {
                return 0.0;
            }
            if self.is_wavelet_along(a) && c - start >= w / 2 {
                sign = -sign;
            }
        }
        sign / ((w * w * w) as f64).sqrt()
    }
}

/// Haar basis value of the coefficient at flat index `coefficient` (cube layout) evaluated at
/// cell `cell`, for a cube of side `side`. This is one entry of the matrix H of (6.7).
pub fn haar_basis_value(side: usize, coefficient: usize, cell: [usize; 3]) -> f64 {
    let z = coefficient % side;
    let r = coefficient / side;
    CoefficientAddress::from_coords([r / side, r % side, z]).haar_value(side, cell)
}

/// The outcome of keeping the largest coefficients of one component.
#[derive(Debug, Clone, PartialEq)]
pub struct Thresholded {
    /// Flat indices of the kept coefficients, increasing.
    pub indices: Vec<u32>,
    /// Relative error `‖f − f̂‖ / ‖f‖` predicted from the energy of the dropped coefficients
    /// (exact for orthonormal wavelets).
    pub relative_error: f64,
    /// Number of non-zero coefficients of the component.
    pub nonzero: usize,
}

/// Keeps the fewest largest-magnitude coefficients whose dropped energy is at most
/// `target² · total energy`, i.e. relative L2 error ≤ `target` for an orthonormal transform.
///
/// A zero function keeps nothing. Ties are broken by index so that the result is deterministic.
pub fn keep_for_relative_error(coefficients: &[f32], target: f64) -> Result<Thresholded> {
    if !(0.0..=1.0).contains(&target) {
        return Err(WaveletError::BadErrorTarget(target));
    }
    if let Some(index) = crate::cube::first_non_finite(coefficients) {
        return Err(WaveletError::NonFinite { index });
    }
    let mut nz = nonzero_magnitudes(coefficients);
    let nonzero = nz.len();
    let total: f64 = nz.iter().map(|(a, _)| (*a as f64) * (*a as f64)).sum();
    if total == 0.0 {
        return Ok(Thresholded {
            indices: Vec::new(),
            relative_error: 0.0,
            nonzero,
        });
    }
    // Largest first; the index breaks ties.
    nz.sort_unstable_by(|a, b| b.0.total_cmp(&a.0).then(a.1.cmp(&b.1)));
    let allowed = target * target * total;
    // Drop the smallest coefficients while their summed energy stays within the budget;
    // summing from the small end keeps the tail energy accurate.
    let mut k = nz.len();
    let mut dropped = 0.0f64;
    while k > 0 {
        let a = nz[k - 1].0 as f64;
        if dropped + a * a > allowed {
            break;
        }
        dropped += a * a;
        k -= 1;
    }
    let remaining = dropped;
    let mut indices: Vec<u32> = nz[..k].iter().map(|p| p.1).collect();
    indices.sort_unstable();
    Ok(Thresholded {
        indices,
        relative_error: (remaining / total).sqrt(),
        nonzero,
    })
}

/// `(|c|, index)` of the non-zero coefficients.
fn nonzero_magnitudes(coefficients: &[f32]) -> Vec<(f32, u32)> {
    coefficients
        .iter()
        .enumerate()
        .filter(|(_, c)| **c != 0.0)
        .map(|(i, c)| (c.abs(), i as u32))
        .collect()
}

/// Flat indices (increasing) of the `count` largest-magnitude coefficients (ties by index).
pub fn keep_largest(coefficients: &[f32], count: usize) -> Vec<u32> {
    let mut nz = nonzero_magnitudes(coefficients);
    let cmp = |a: &(f32, u32), b: &(f32, u32)| b.0.total_cmp(&a.0).then(a.1.cmp(&b.1));
    if count < nz.len() {
        nz.select_nth_unstable_by(count, cmp);
        nz.truncate(count);
    }
    let mut indices: Vec<u32> = nz.into_iter().map(|p| p.1).collect();
    indices.sort_unstable();
    indices
}

/// Sets every coefficient whose index is not in `keep` (increasing) to zero.
pub fn zero_all_but(coefficients: &mut [f32], keep: &[u32]) {
    let mut next = keep.iter().peekable();
    for (i, c) in coefficients.iter_mut().enumerate() {
        if next.peek().is_some_and(|&&k| k as usize == i) {
            next.next();
        } else {
            *c = 0.0;
        }
    }
}

/// Relative L2 error `‖a − b‖ / ‖a‖` (f64 accumulation); 0 when both are zero, infinite when
/// only `a` is.
pub fn relative_l2_error(reference: &[f32], approx: &[f32]) -> f64 {
    let (mut num, mut den) = (0.0f64, 0.0f64);
    for (&a, &b) in reference.iter().zip(approx) {
        let d = a as f64 - b as f64;
        num += d * d;
        den += (a as f64) * (a as f64);
    }
    if den == 0.0 {
        if num == 0.0 {
            0.0
        } else {
            f64::INFINITY
        }
    } else {
        (num / den).sqrt()
    }
}

/// Factor relating Haar coefficients of a coarse grid of block means to those of the fine cube.
///
/// If a function on a cube of side `fine` is constant on blocks of `(fine/coarse)³` cells and
/// `a` is the cube of side `coarse` holding the block values, then for every coefficient
/// position `(x, y, z)` of the coarse full transform, the fine full transform has at the same
/// position the coarse coefficient times `(fine/coarse)^{3/2}`. Thesis §6.3 estimates the lowest
/// levels of a sparsely sampled BRDF this way from a 16³ grid of averages.
pub fn coarse_to_fine_scale(fine: usize, coarse: usize) -> f64 {
    let w = fine as f64 / coarse as f64;
    w * w.sqrt()
}
