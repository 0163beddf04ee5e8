//! 3D nonstandard discrete wavelet transforms (thesis §6.1).

use crate::cube::Cube;
use crate::error::{Result, WaveletError};
use rayon::prelude::*;
use std::f32::consts::FRAC_1_SQRT_2;

const SQRT_2: f32 = std::f32::consts::SQRT_2;
const SQRT_3: f32 = 1.732_050_8;

/// The wavelet filter of a transform (see [`forward`]).
///
/// Three filters are available, all scaled so that low-pass outputs have DC gain √2 (so
/// coefficient magnitudes are comparable across filters for thresholding):
///
/// * [`Wavelet::Haar`]: orthonormal Haar, `lo = (a + b)/√2`, `hi = (a − b)/√2` (PyWavelets' sign).
/// * [`Wavelet::Cdf53`]: the biorthogonal CDF 5/3 (LeGall) wavelet by lifting, whole-sample
///   symmetric extension at both ends; predict `d −= (e_i + e_{i+1})/2`, update
///   `s += (d_{i−1} + d_i)/4`, then `s·√2`, `d/√2`.
/// * [`Wavelet::Daub4`]: the orthonormal Daubechies-4 wavelet (two vanishing moments) by its
///   three-step lifting factorisation (Daubechies & Sweldens 1998), periodic extension.
///
/// Passes run in parallel with rayon: the θd and φd steps over θh slabs, the θh step over θd.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default)]
pub enum Wavelet {
    /// Orthonormal Haar (the thesis's choice).
    #[default]
    Haar,
    /// Biorthogonal CDF 5/3 (LeGall) by lifting, symmetric boundaries.
    Cdf53,
    /// Orthonormal Daubechies-4 by lifting, periodic boundaries.
    Daub4,
}

impl Wavelet {
    /// All filters, in the order Haar, CDF 5/3, Daubechies-4.
    pub const ALL: [Wavelet; 3] = [Wavelet::Haar, Wavelet::Cdf53, Wavelet::Daub4];

    /// Whether the transform is orthonormal (Parseval holds, so the energy of discarded
    /// coefficients equals the squared reconstruction error).
    pub fn is_orthonormal(self) -> bool {
        matches!(self, Wavelet::Haar | Wavelet::Daub4)
    }

    /// Short name (`haar`, `cdf53`, `db4`).
    pub fn name(self) -> &'static str {
        match self {
            Wavelet::Haar => "haar",
            Wavelet::Cdf53 => "cdf53",
            Wavelet::Daub4 => "db4",
        }
    }
}

impl std::str::FromStr for Wavelet {
    type Err = String;
    fn from_str(s: &str) -> std::result::Result<Self, String> {
        match s.to_ascii_lowercase().as_str() {
            "haar" => Ok(Wavelet::Haar),
            "cdf53" | "cdf5/3" | "legall" | "bior2.2" => Ok(Wavelet::Cdf53),
            "db4" | "daub4" | "d4" | "db2" => Ok(Wavelet::Daub4),
            other => Err(format!("unknown wavelet `{other}` (haar, cdf53, db4)")),
        }
    }
}

/// One forward step of the 1D transform applied to `s` rows of `len` values each.
///
/// `src` holds the rows in natural order (row `r` at `r·len`); `dst` receives the `s/2` low-pass
/// rows followed by the `s/2` high-pass rows. With `len = 1` this is the ordinary 1D transform.
pub fn forward_rows(wavelet: Wavelet, src: &[f32], dst: &mut [f32], s: usize, len: usize) {
    debug_assert!(s >= 2 && s % 2 == 0);
    let h = s / 2;
    let (lo, hi) = dst[..s * len].split_at_mut(h * len);
    if wavelet == Wavelet::Haar {
        for i in 0..h {
            let a = &src[2 * i * len..][..len];
            let b = &src[(2 * i + 1) * len..][..len];
            let l = &mut lo[i * len..][..len];
            let d = &mut hi[i * len..][..len];
            for k in 0..len {
                l[k] = (a[k] + b[k]) * FRAC_1_SQRT_2;
                d[k] = (a[k] - b[k]) * FRAC_1_SQRT_2;
            }
        }
        return;
    }
    for i in 0..h {
        lo[i * len..][..len].copy_from_slice(&src[2 * i * len..][..len]);
        hi[i * len..][..len].copy_from_slice(&src[(2 * i + 1) * len..][..len]);
    }
    match wavelet {
        Wavelet::Haar => unreachable!("handled above"),
        Wavelet::Cdf53 => {
            for i in 0..h {
                let nxt = (i + 1).min(h - 1);
                axpy2(
                    &mut hi[i * len..][..len],
                    -0.5,
                    &lo[i * len..][..len],
                    &lo[nxt * len..][..len],
                );
            }
            for i in 0..h {
                let prv = i.saturating_sub(1);
                axpy2(
                    &mut lo[i * len..][..len],
                    0.25,
                    &hi[prv * len..][..len],
                    &hi[i * len..][..len],
                );
            }
            scale(lo, SQRT_2);
            scale(hi, FRAC_1_SQRT_2);
        }
        Wavelet::Daub4 => {
            for i in 0..h {
                axpy1(&mut lo[i * len..][..len], SQRT_3, &hi[i * len..][..len]);
            }
            let (c0, c1) = (SQRT_3 / 4.0, (SQRT_3 - 2.0) / 4.0);
            for i in 0..h {
                let prv = (i + h - 1) % h;
                axpy_pair(
                    &mut hi[i * len..][..len],
                    -c0,
                    &lo[i * len..][..len],
                    -c1,
                    &lo[prv * len..][..len],
                );
            }
            for i in 0..h {
                let nxt = (i + 1) % h;
                axpy1(&mut lo[i * len..][..len], -1.0, &hi[nxt * len..][..len]);
            }
            scale(lo, (SQRT_3 - 1.0) * FRAC_1_SQRT_2);
            scale(hi, (SQRT_3 + 1.0) * FRAC_1_SQRT_2);
        }
    }
}

/// One inverse step: `src` holds low-pass rows then high-pass rows (it is used as scratch and
/// overwritten); `dst` receives the `s` reconstructed rows in natural order.
pub fn inverse_rows(wavelet: Wavelet, src: &mut [f32], dst: &mut [f32], s: usize, len: usize) {
    debug_assert!(s >= 2 && s % 2 == 0);
    let h = s / 2;
    let (lo, hi) = src[..s * len].split_at_mut(h * len);
    match wavelet {
        Wavelet::Haar => {
            for i in 0..h {
                let l = &lo[i * len..][..len];
                let d = &hi[i * len..][..len];
                let (a, b) = dst[2 * i * len..][..2 * len].split_at_mut(len);
                for k in 0..len {
                    a[k] = (l[k] + d[k]) * FRAC_1_SQRT_2;
                    b[k] = (l[k] - d[k]) * FRAC_1_SQRT_2;
                }
            }
            return;
        }
        Wavelet::Cdf53 => {
            scale(lo, FRAC_1_SQRT_2);
            scale(hi, SQRT_2);
            for i in 0..h {
                let prv = i.saturating_sub(1);
                axpy2(
                    &mut lo[i * len..][..len],
                    -0.25,
                    &hi[prv * len..][..len],
                    &hi[i * len..][..len],
                );
            }
            for i in 0..h {
                let nxt = (i + 1).min(h - 1);
                axpy2(
                    &mut hi[i * len..][..len],
                    0.5,
                    &lo[i * len..][..len],
                    &lo[nxt * len..][..len],
                );
            }
        }
        Wavelet::Daub4 => {
            scale(lo, (SQRT_3 + 1.0) * FRAC_1_SQRT_2);
            scale(hi, (SQRT_3 - 1.0) * FRAC_1_SQRT_2);
            for i in 0..h {
                let nxt = (i + 1) % h;
                axpy1(&mut lo[i * len..][..len], 1.0, &hi[nxt * len..][..len]);
            }
            let (c0, c1) = (SQRT_3 / 4.0, (SQRT_3 - 2.0) / 4.0);
            for i in 0..h {
                let prv = (i + h - 1) % h;
                axpy_pair(
                    &mut hi[i * len..][..len],
                    c0,
                    &lo[i * len..][..len],
                    c1,
                    &lo[prv * len..][..len],
                );
            }
            for i in 0..h {
                axpy1(&mut lo[i * len..][..len], -SQRT_3, &hi[i * len..][..len]);
            }
        }
    }
    for i in 0..h {
        dst[2 * i * len..][..len].copy_from_slice(&lo[i * len..][..len]);
        dst[(2 * i + 1) * len..][..len].copy_from_slice(&hi[i * len..][..len]);
    }
}

/// `y += a·(u + v)`.
#[inline]
fn axpy2(y: &mut [f32], a: f32, u: &[f32], v: &[f32]) {
    for ((y, u), v) in y.iter_mut().zip(u).zip(v) {
        *y += a * (u + v);
    }
}

/// `y += a·u`.
#[inline]
fn axpy1(y: &mut [f32], a: f32, u: &[f32]) {
    for (y, u) in y.iter_mut().zip(u) {
        *y += a * u;
    }
}

/// `y += a·u + b·v`.
#[inline]
fn axpy_pair(y: &mut [f32], a: f32, u: &[f32], b: f32, v: &[f32]) {
    for ((y, u), v) in y.iter_mut().zip(u).zip(v) {
        *y += a * u + b * v;
    }
}

#[inline]
fn scale(y: &mut [f32], a: f32) {
    for v in y {
        *v *= a;
    }
}

fn check_levels(cube: &Cube, levels: u32) -> Result<()> {
    let max = cube.max_levels();
    if levels > max {
        return Err(WaveletError::TooManyLevels {
            levels,
            side: cube.side(),
            max,
        });
    }
    Ok(())
}

/// Forward nonstandard transform with `levels` decomposition levels (0 = identity,
/// `cube.max_levels()` = full decomposition down to one scaling coefficient): the 3D
/// nonstandard discrete wavelet transform of thesis §6.1.
///
/// One decomposition level applies one step of the 1D transform along each of the three axes of
/// the current approximation sub-cube `[0, s)³`; the next level works on the low-pass octant
/// `[0, s/2)³`. Coefficients are stored in place in the usual "Mallat" layout: along each axis
/// the low-pass half comes first. This is the layout of `pywt.coeffs_to_array(pywt.wavedecn(..))`
/// and the nonstandard decomposition of Beylkin, Coifman and Rokhlin the thesis uses.
///
/// # Examples
///
/// ```
/// use wavelet::{forward, inverse, Cube, Wavelet};
///
/// // a 16³ cube, transformed and back (the MERL layout is a 256³ cube: `Layout::MERL_HAAR`)
/// let side = 16;
/// let values: Vec<f32> = (0..side * side * side).map(|i| ((i % 13) as f32).sin()).collect();
/// let mut cube = Cube::from_vec(side, values.clone()).unwrap();
/// forward(&mut cube, Wavelet::Haar, 4).unwrap();
/// // the orthonormal Haar transform keeps the energy
/// let energy: f64 = values.iter().map(|v| (*v as f64).powi(2)).sum();
/// assert!((cube.energy() - energy).abs() < 1e-3 * energy);
/// inverse(&mut cube, Wavelet::Haar, 4).unwrap();
/// assert!(cube.data().iter().zip(&values).all(|(a, b)| (a - b).abs() < 1e-4));
/// ```
pub fn forward(cube: &mut Cube, wavelet: Wavelet, levels: u32) -> Result<()> {
    check_levels(cube, levels)?;
    let n = cube.side();
    for l in 0..levels {
        level_step(cube.data_mut(), n, n >> l, wavelet, Direction::Forward);
    }
    Ok(())
}

/// Inverse of [`forward`] with the same number of levels.
pub fn inverse(cube: &mut Cube, wavelet: Wavelet, levels: u32) -> Result<()> {
    check_levels(cube, levels)?;
    let n = cube.side();
    for l in (0..levels).rev() {
        level_step(cube.data_mut(), n, n >> l, wavelet, Direction::Inverse);
    }
    Ok(())
}

/// Full forward decomposition (log2 side levels).
pub fn forward_full(cube: &mut Cube, wavelet: Wavelet) -> Result<()> {
    let levels = cube.max_levels();
    forward(cube, wavelet, levels)
}

/// Full inverse decomposition (log2 side levels).
pub fn inverse_full(cube: &mut Cube, wavelet: Wavelet) -> Result<()> {
    let levels = cube.max_levels();
    inverse(cube, wavelet, levels)
}

#[derive(Clone, Copy, PartialEq, Eq)]
enum Direction {
    Forward,
    Inverse,
}

/// A raw pointer that may cross threads; every user writes a disjoint set of elements.
#[derive(Clone, Copy)]
struct SharedPtr(*mut f32);
// SAFETY: the pointer is only dereferenced on disjoint element sets from different threads
// while the owning `&mut [f32]` is borrowed by `level_step` (see the θh pass below).
unsafe impl Send for SharedPtr {}
unsafe impl Sync for SharedPtr {}

impl SharedPtr {
    #[inline]
    fn get(self) -> *mut f32 {
        self.0
    }
}

/// One level of the transform on the sub-cube `[0, s)³` of a cube of side `n`.
fn level_step(data: &mut [f32], n: usize, s: usize, wavelet: Wavelet, dir: Direction) {
    let plane = n * n;
    let step = |src: &mut [f32], dst: &mut [f32], len: usize| match dir {
        Direction::Forward => forward_rows(wavelet, src, dst, s, len),
        Direction::Inverse => inverse_rows(wavelet, src, dst, s, len),
    };
    // θd and φd steps, slab by slab (axis 0 fixed). Within a slab the rows y < s are the
    // 1D signals of the φd step, and the rows themselves are the samples of the θd step.
    let slab_pass = |scratch: &mut Vec<f32>, slab: &mut [f32]| {
        scratch.resize(2 * s * s, 0.0);
        let (a, b) = scratch.split_at_mut(s * s);
        // φd (axis 2): each row is a signal of s scalars. Haar runs on the rows directly; the
        // lifting filters run on the transposed block, where the φd samples become rows of
        // s values and the lifting steps vectorise.
        if wavelet == Wavelet::Haar || s < 8 {
            for y in 0..s {
                let row = &mut slab[y * n..y * n + s];
                a[..s].copy_from_slice(row);
                step(&mut a[..s], row, 1);
            }
        } else {
            for y in 0..s {
                let row = &slab[y * n..y * n + s];
                for (z, &v) in row.iter().enumerate() {
                    a[z * s + y] = v;
                }
            }
            step(a, b, s);
            for y in 0..s {
                let row = &mut slab[y * n..y * n + s];
                for (z, v) in row.iter_mut().enumerate() {
                    *v = b[z * s + y];
                }
            }
        }
        // θd (axis 1): the s rows are the samples, each a vector of s values.
        for y in 0..s {
            a[y * s..(y + 1) * s].copy_from_slice(&slab[y * n..y * n + s]);
        }
        step(a, b, s);
        for y in 0..s {
            slab[y * n..y * n + s].copy_from_slice(&b[y * s..(y + 1) * s]);
        }
    };
    // θh (axis 0): for fixed y, the rows (x, y, ·) over x are the samples.
    let run_axis0 = |data: &mut [f32]| {
        let ptr = SharedPtr(data.as_mut_ptr());
        let axis0_pass = |scratch: &mut Vec<f32>, y: usize| {
            scratch.resize(2 * s * s, 0.0);
            let (a, b) = scratch.split_at_mut(s * s);
            for x in 0..s {
                // SAFETY: row (x, y, 0..s) lies inside `data` (x, y < s <= n); for this `y` no
                // other task touches these elements during the pass, and `data` itself is not
                // used while the pass runs.
                let row =
                    unsafe { std::slice::from_raw_parts(ptr.get().add(x * plane + y * n), s) };
                a[x * s..(x + 1) * s].copy_from_slice(row);
            }
            step(a, b, s);
            for x in 0..s {
                // SAFETY: as above; the rows written are exactly the rows read for this `y`.
                let row =
                    unsafe { std::slice::from_raw_parts_mut(ptr.get().add(x * plane + y * n), s) };
                row.copy_from_slice(&b[x * s..(x + 1) * s]);
            }
        };
        (0..s)
            .into_par_iter()
            .with_min_len(4.min(s))
            .for_each_init(Vec::new, axis0_pass);
    };
    let run_slabs = |data: &mut [f32]| {
        data[..s * plane]
            .par_chunks_mut(plane)
            .with_min_len(4.min(s))
            .for_each_init(Vec::new, slab_pass);
    };
    match dir {
        Direction::Forward => {
            run_slabs(data);
            run_axis0(data);
        }
        Direction::Inverse => {
            run_axis0(data);
            run_slabs(data);
        }
    }
}
