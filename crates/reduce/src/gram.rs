//! Streaming Gram matrix `B = Yᵀ Y` of a corpus (thesis eqs. 2.23, 4.1).

use nalgebra::DMatrix;
use rayon::prelude::*;

use crate::error::{ReduceError, Result};
use crate::ordered::{add_into, group_size, reduce_in_order};

/// Number of dimensions per streamed block of [`column_means`] and of the PCA passes (a
/// multiple of the SIMD width).
pub const BLOCK: usize = 512;

const LANES: usize = 16;
const TILE_R: usize = 4;
const TILE_C: usize = 4;

/// Number of dimensions per block of the Gram kernels (a multiple of the SIMD width): long
/// enough to amortise the horizontal sums of a register tile, short enough for the block
/// (`n × GRAM_BLOCK × 4` bytes, 384 kB for 96 materials) to stay in the L2 cache.
const GRAM_BLOCK: usize = 1024;

/// Row stride of the Gram scratch buffer, in values: a multiple of 16 so that with the buffer
/// started on a 64-byte boundary every SIMD load is aligned (unaligned zmm loads crossed a
/// cache line every time and cost the kernel a quarter of its speed), plus one cache line so
/// that the rows do not all fall into the same L1 sets.
const GRAM_STRIDE: usize = GRAM_BLOCK + 16;

/// The dot-product kernels of [`gram_matrix_with`].
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum GramKernel {
    /// Plain Rust, 16 independent `f32` lanes (vectorised by the compiler for the baseline
    /// target).
    Portable,
    /// AVX2 + FMA intrinsics: 3 × 4 tiles of 8-lane accumulators (12 of the 16 registers).
    Avx2,
    /// AVX-512F intrinsics: 6 × 4 tiles of 16-lane accumulators.
    Avx512,
    /// faer's cache-blocked matrix product on each block of 1024 dimensions (lower triangle
    /// only for a Gram matrix), summed in `f64`: the kernel for many rows, where one block of
    /// all rows no longer fits a cache and the register tiles above would stream it from
    /// memory once per tile column.
    Blocked,
}

/// Rows above which [`gram_matrix`] uses [`GramKernel::Blocked`]; [`cross_gram_matrix`] uses it
/// above half as many rows in all (`m + n`), since its register-tiled path forms the Gram of
/// the stacked rows, at least twice the work of the product. Measured with
/// `cargo bench -p reduce --bench gram -- 3 kernels rows=N` on 2 cores with AVX-512: the
/// tiled kernel 1.29 s against 1.65 s at 512 rows, 2.60 s against 2.29 s at 1,024.
pub const BLOCKED_ROWS: usize = 768;

impl GramKernel {
    /// The kernel [`gram_matrix`] uses for `rows` rows: [`GramKernel::Blocked`] above
    /// [`BLOCKED_ROWS`], else [`GramKernel::detect`].
    pub fn for_rows(rows: usize) -> GramKernel {
        if rows > BLOCKED_ROWS {
            GramKernel::Blocked
        } else {
            GramKernel::detect()
        }
    }

    /// The fastest register-tiled kernel this CPU supports.
    pub fn detect() -> GramKernel {
        if GramKernel::Avx512.is_available() {
            GramKernel::Avx512
        } else if GramKernel::Avx2.is_available() {
            GramKernel::Avx2
        } else {
            GramKernel::Portable
        }
    }

    /// Whether this CPU can run the kernel.
    pub fn is_available(self) -> bool {
        match self {
            GramKernel::Portable | GramKernel::Blocked => true,
            #[cfg(target_arch = "x86_64")]
            GramKernel::Avx2 => {
                std::arch::is_x86_feature_detected!("avx2")
                    && std::arch::is_x86_feature_detected!("fma")
            }
            #[cfg(target_arch = "x86_64")]
            GramKernel::Avx512 => std::arch::is_x86_feature_detected!("avx512f"),
            #[cfg(not(target_arch = "x86_64"))]
            _ => false,
        }
    }

    fn function(self) -> Kernel {
        match self {
            #[cfg(target_arch = "x86_64")]
            GramKernel::Avx512 => block_gram_avx512,
            #[cfg(target_arch = "x86_64")]
            GramKernel::Avx2 => block_gram_avx2,
            _ => block_gram_portable,
        }
    }
}

/// Gram matrix `G[i][j] = Σ_d (y_i[d] − m[d]) (y_j[d] − m[d])` of `n` rows of length `dim`.
///
/// `data` is row-major (`n × dim`); `mean`, when given, is subtracted from every row on the
/// fly (pass `None` for the raw `Yᵀ Y`). Partial sums over one block of 1024 values are
/// formed in `f32`, everything else in `f64`. Uses [`GramKernel::for_rows`]. This is the
/// streamed Gram matrix `B = Yᵀ Y` of thesis eqs. 2.23 and 4.1.
///
/// The corpus is stored material-major: `n` rows of `dim` `f32` values. The Gram matrix is
/// accumulated over blocks of 1024 consecutive dimensions. Each rayon task copies one block
/// (optionally mean-centred) into a small `n × 1024` scratch buffer, forms the block's dot
/// products in `f32` with a register-tiled SIMD kernel ([`GramKernel`], chosen at run time) and adds them into its own `f64`
/// accumulator; the per-task accumulators are summed at the end. Extra memory is therefore
/// `threads × (n × 1024 × 4 + n² × 8)` bytes, independent of `dim`: the data itself is never
/// copied or transposed.
///
/// # Examples
///
/// ```
/// // two rows of three values, centred on their mean (1.5, 1.5, 1.5)
/// let data = [1.0f32, 1.0, 1.0, 2.0, 2.0, 2.0];
/// let mean = [1.5f32; 3];
/// let g = reduce::gram_matrix(&data, 2, 3, Some(&mean)).unwrap();
/// assert_eq!(g.shape(), (2, 2));
/// assert!((g[(0, 0)] - 0.75).abs() < 1e-12 && (g[(0, 1)] + 0.75).abs() < 1e-12);
/// ```
pub fn gram_matrix(
    data: &[f32],
    n: usize,
    dim: usize,
    mean: Option<&[f32]>,
) -> Result<DMatrix<f64>> {
    gram_matrix_with(data, n, dim, mean, GramKernel::for_rows(n))
}

/// [`gram_matrix`] with a given kernel; an error if the CPU cannot run it.
pub fn gram_matrix_with(
    data: &[f32],
    n: usize,
    dim: usize,
    mean: Option<&[f32]>,
    kernel: GramKernel,
) -> Result<DMatrix<f64>> {
    if !kernel.is_available() {
        return Err(ReduceError::InvalidParameter(format!(
            "Gram kernel {kernel:?} is not supported by this CPU"
        )));
    }
    ReduceError::check_size("gram data length (n × dim)", n * dim, data.len())?;
    if let Some(m) = mean {
        ReduceError::check_size("gram mean length", dim, m.len())?;
    }
    if n == 0 {
        return Ok(DMatrix::zeros(0, 0));
    }
    if kernel == GramKernel::Blocked {
        let mut lower = vec![0.0f64; n * n];
        accumulate_blocked(data, n, None, dim, mean, &mut lower);
        return Ok(DMatrix::from_fn(n, n, |i, j| {
            lower[i.max(j) * n + i.min(j)]
        }));
    }
    let kernel = kernel.function();
    const BLOCK: usize = GRAM_BLOCK;
    const STRIDE: usize = GRAM_STRIDE;
    let nblocks = dim.div_ceil(BLOCK);
    let groups = (0..nblocks).into_par_iter().fold_chunks(
        group_size(nblocks, n * n * 8),
        || {
            (
                vec![0.0f64; n * n],
                vec![0.0f32; n * STRIDE + 16],
                vec![0.0f32; n * n],
            )
        },
        |(mut acc, mut buf_all, mut part), b| {
            let buf = aligned_scratch(&mut buf_all, n * STRIDE);
            let c0 = b * BLOCK;
            let len = BLOCK.min(dim - c0);
            for r in 0..n {
                let src = &data[r * dim + c0..r * dim + c0 + len];
                let dst = &mut buf[r * STRIDE..r * STRIDE + len];
                match mean {
                    Some(m) => {
                        for ((d, s), mu) in dst.iter_mut().zip(src).zip(&m[c0..c0 + len]) {
                            *d = s - mu;
                        }
                    }
                    None => dst.copy_from_slice(src),
                }
            }
            kernel(buf, n, STRIDE, len, &mut part);
            for (a, p) in acc.iter_mut().zip(&part) {
                *a += *p as f64;
            }
            (acc, buf_all, part)
        },
    );
    let upper = reduce_in_order(
        groups.map(|(acc, _, _)| acc),
        || vec![0.0f64; n * n],
        add_into,
    );
    // Only j >= i was computed (row i, column j); mirror it.
    let mut g = DMatrix::zeros(n, n);
    for i in 0..n {
        for j in i..n {
            let v = upper[i * n + j];
            g[(i, j)] = v;
            g[(j, i)] = v;
        }
    }
    Ok(g)
}

/// Cross Gram matrix `G[i][j] = Σ_d a_i[d] · b_j[d]` (that is `A Bᵀ`) of the `m` rows of `a`
/// and the `n` rows of `b`, all of length `dim`, row-major.
///
/// Each block of 1024 dimensions of both inputs is copied into one `(m + n) × 1024` scratch
/// buffer and the kernels of [`gram_matrix`] run on it; the `m × n` corner of the block Gram is
/// accumulated in `f64`. (The kernels form the whole upper triangle of the stacked block, so
/// the cost is that of a Gram of `m + n` rows.) Above half of [`BLOCKED_ROWS`] rows in all, each block
/// is instead one matrix product of faer ([`GramKernel::Blocked`]).
///
/// ```
/// let a = [1.0f32, 2.0, 3.0, 4.0]; // 2 rows of 2
/// let b = [1.0f32, 0.0, 0.0, 1.0, 1.0, 1.0]; // 3 rows of 2
/// let g = reduce::cross_gram_matrix(&a, 2, &b, 3, 2).unwrap();
/// assert_eq!((g.nrows(), g.ncols()), (2, 3));
/// assert_eq!(g[(1, 2)], 7.0);
/// ```
pub fn cross_gram_matrix(
    a: &[f32],
    m: usize,
    b: &[f32],
    n: usize,
    dim: usize,
) -> Result<DMatrix<f64>> {
    ReduceError::check_size("cross gram left data length (m × dim)", m * dim, a.len())?;
    ReduceError::check_size("cross gram right data length (n × dim)", n * dim, b.len())?;
    if m == 0 || n == 0 || dim == 0 {
        return Ok(DMatrix::zeros(m, n));
    }
    if GramKernel::for_rows(2 * (m + n)) == GramKernel::Blocked {
        let mut acc = vec![0.0f64; m * n];
        accumulate_blocked(a, m, Some((b, n)), dim, None, &mut acc);
        return Ok(DMatrix::from_fn(m, n, |i, j| acc[i * n + j]));
    }
    let kernel = GramKernel::detect().function();
    const BLOCK: usize = GRAM_BLOCK;
    const STRIDE: usize = GRAM_STRIDE;
    let rows = m + n;
    let nblocks = dim.div_ceil(BLOCK);
    let groups = (0..nblocks).into_par_iter().fold_chunks(
        group_size(nblocks, m * n * 8),
        || {
            (
                vec![0.0f64; m * n],
                vec![0.0f32; rows * STRIDE + 16],
                vec![0.0f32; rows * rows],
            )
        },
        |(mut acc, mut buf_all, mut part), blk| {
            let buf = aligned_scratch(&mut buf_all, rows * STRIDE);
            let c0 = blk * BLOCK;
            let len = BLOCK.min(dim - c0);
            for r in 0..rows {
                let src = if r < m {
                    &a[r * dim + c0..r * dim + c0 + len]
                } else {
                    let q = r - m;
                    &b[q * dim + c0..q * dim + c0 + len]
                };
                buf[r * STRIDE..r * STRIDE + len].copy_from_slice(src);
            }
            kernel(buf, rows, STRIDE, len, &mut part);
            for i in 0..m {
                for j in 0..n {
                    acc[i * n + j] += part[i * rows + m + j] as f64;
                }
            }
            (acc, buf_all, part)
        },
    );
    let corner = reduce_in_order(
        groups.map(|(acc, _, _)| acc),
        || vec![0.0f64; m * n],
        add_into,
    );
    Ok(DMatrix::from_fn(m, n, |i, j| corner[i * n + j]))
}

/// Adds the products of the rows of `a` (`m × dim`, row-major, centred by `mean` when given)
/// with the rows of `b` (`n × dim`) into `acc` (row-major `m × n`); without `b`, the products
/// of `a` with itself, of which only the lower triangle (`j ≤ i`) is formed and added.
///
/// Each block of [`GRAM_BLOCK`] dimensions is one faer product in `f32` (parallel over its
/// output tiles, so the sums do not depend on the number of threads), added into `acc` in
/// `f64`, as the register-tiled kernels do. Extra memory: `m × n × 4` bytes for the block
/// product and, when centring, `m × 1024 × 4` for the centred block.
fn accumulate_blocked(
    a: &[f32],
    m: usize,
    b: Option<(&[f32], usize)>,
    dim: usize,
    mean: Option<&[f32]>,
    acc: &mut [f64],
) {
    use faer::linalg::matmul::triangular::{matmul, BlockStructure};
    use faer::{Accum, MatMut, MatRef, Par};
    let n = b.map_or(m, |(_, n)| n);
    debug_assert!(a.len() == m * dim && acc.len() == m * n);
    let mut centred = if mean.is_some() {
        vec![0.0f32; m * GRAM_BLOCK]
    } else {
        Vec::new()
    };
    let mut part = vec![0.0f32; m * n];
    for c0 in (0..dim).step_by(GRAM_BLOCK) {
        let len = GRAM_BLOCK.min(dim - c0);
        let lhs = match mean {
            Some(mu) => {
                let mu = &mu[c0..c0 + len];
                centred[..m * len]
                    .par_chunks_mut(len)
                    .enumerate()
                    .for_each(|(r, row)| {
                        let src = &a[r * dim + c0..r * dim + c0 + len];
                        for ((d, s), mu) in row.iter_mut().zip(src).zip(mu) {
                            *d = s - mu;
                        }
                    });
                MatRef::from_row_major_slice(&centred[..m * len], m, len)
            }
            None => MatRef::from_row_major_slice_with_stride(&a[c0..], m, len, dim),
        };
        let (rhs, structure) = match b {
            Some((b, n)) => (
                MatRef::from_row_major_slice_with_stride(&b[c0..], n, len, dim).transpose(),
                BlockStructure::Rectangular,
            ),
            None => (lhs.transpose(), BlockStructure::TriangularLower),
        };
        matmul(
            MatMut::from_row_major_slice_mut(&mut part, m, n),
            structure,
            Accum::Replace,
            lhs,
            BlockStructure::Rectangular,
            rhs,
            BlockStructure::Rectangular,
            1.0f32,
            Par::rayon(0),
        );
        let lower_only = b.is_none();
        acc.par_chunks_mut(n)
            .zip(part.par_chunks(n))
            .enumerate()
            .for_each(|(i, (row, p))| {
                let end = if lower_only { i + 1 } else { n };
                for (s, v) in row[..end].iter_mut().zip(&p[..end]) {
                    *s += *v as f64;
                }
            });
    }
}

/// Adds the lower triangle (`j ≤ i`) of the Gram matrix `Yᵀ Y` of the `n` rows of `data`
/// (`n × dim`, row-major) into `lower` (row-major `n × n`; the upper triangle is left as it
/// is), with the kernel [`GramKernel::for_rows`] picks: an out-of-core Gram sums its panels
/// this way into one `f64` matrix.
pub fn accumulate_gram_lower(data: &[f32], n: usize, dim: usize, lower: &mut [f64]) -> Result<()> {
    if data.len() != n * dim || lower.len() != n * n {
        return Err(ReduceError::Dimension {
            what: "gram accumulation (n × dim data, n × n sums)",
            expected: n * dim,
            got: data.len(),
        });
    }
    if GramKernel::for_rows(n) == GramKernel::Blocked {
        accumulate_blocked(data, n, None, dim, None, lower);
        return Ok(());
    }
    let part = gram_matrix(data, n, dim, None)?;
    for i in 0..n {
        for j in 0..=i {
            lower[i * n + j] += part[(i, j)];
        }
    }
    Ok(())
}

/// The `len` values of `buf` (allocated with 16 spare values) from its first 64-byte boundary,
/// which the aligned loads of the SIMD kernels need (a `Vec<f32>` is only 4-byte aligned).
fn aligned_scratch(buf: &mut [f32], len: usize) -> &mut [f32] {
    let off = (buf.as_ptr() as usize / 4).wrapping_neg() % 16;
    &mut buf[off..off + len]
}

type Kernel = fn(&[f32], usize, usize, usize, &mut [f32]);

/// One register-tiled SIMD kernel body for both instruction sets: `$tr × $tc` tiles of
/// `$w`-lane accumulators. Per step the `$tr` row vectors are loaded once and each of the `$tc`
/// column vectors is loaded and multiplied into them (`$tr·$tc + $tr + 1` vector registers). Tiles
/// at the right and bottom edges fall back to [`dot`].
#[cfg(target_arch = "x86_64")]
macro_rules! simd_block_gram {
    (
        $(#[$doc:meta])*
        $safe:ident, $name:ident, $feature:literal, $w:literal, $tr:literal, $tc:literal,
        $vec:ty, $zero:ident, $load:ident, $fmadd:ident, $hsum:expr
    ) => {
        $(#[$doc])*
        fn $safe(buf: &[f32], n: usize, stride: usize, len: usize, out: &mut [f32]) {
            // SAFETY: the kernel is only selected after `GramKernel::is_available` confirmed
            // the CPU features it is compiled for.
            unsafe { $name(buf, n, stride, len, out) }
        }

        #[target_feature(enable = $feature)]
        unsafe fn $name(buf: &[f32], n: usize, stride: usize, len: usize, out: &mut [f32]) {
            use std::arch::x86_64::*;
            const W: usize = $w;
            const TR: usize = $tr;
            const TC: usize = $tc;
            assert!(buf.len() >= n.saturating_sub(1) * stride + len && stride >= len);
            assert!(out.len() >= n * n);
            // Aligned loads: the scratch rows start on 64-byte boundaries (see `GRAM_STRIDE`).
            assert!(buf.as_ptr() as usize % 64 == 0 && stride % 16 == 0);
            let body = len - len % W;
            let base = buf.as_ptr();
            let mut i0 = 0;
            while i0 < n {
                let ri = TR.min(n - i0);
                let mut j0 = i0 - i0 % TC;
                while j0 < n {
                    let cj = TC.min(n - j0);
                    if ri == TR && cj == TC {
                        // SAFETY: rows i0..i0+TR and j0..j0+TC exist (n rows of `stride` ≥
                        // `len` values, checked above) and every load reads W values at
                        // offsets k < body ≤ len.
                        let a: [*const f32; TR] =
                            std::array::from_fn(|r| unsafe { base.add((i0 + r) * stride) });
                        let b: [*const f32; TC] =
                            std::array::from_fn(|c| unsafe { base.add((j0 + c) * stride) });
                        let mut acc: [$vec; TR * TC] = [$zero(); TR * TC];
                        let mut k = 0;
                        while k < body {
                            let va: [$vec; TR] =
                                std::array::from_fn(|r| unsafe { $load(a[r].add(k)) });
                            for c in 0..TC {
                                let vb = $load(b[c].add(k));
                                for r in 0..TR {
                                    acc[r * TC + c] = $fmadd(va[r], vb, acc[r * TC + c]);
                                }
                            }
                            k += W;
                        }
                        for r in 0..TR {
                            for c in 0..TC {
                                let mut s = $hsum(acc[r * TC + c]);
                                for k in body..len {
                                    s += buf[(i0 + r) * stride + k] * buf[(j0 + c) * stride + k];
                                }
                                out[(i0 + r) * n + j0 + c] = s;
                            }
                        }
                    } else {
                        for r in 0..ri {
                            for c in 0..cj {
                                let x = &buf[(i0 + r) * stride..(i0 + r) * stride + len];
                                let y = &buf[(j0 + c) * stride..(j0 + c) * stride + len];
                                out[(i0 + r) * n + j0 + c] = dot_lanes::<true>(x, y);
                            }
                        }
                    }
                    j0 += TC;
                }
                i0 += TR;
            }
        }
    };
}

/// Horizontal sum of the 8 lanes of an AVX register.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2,fma")]
fn hsum256(v: std::arch::x86_64::__m256) -> f32 {
    use std::arch::x86_64::*;
    let s = _mm_add_ps(_mm256_castps256_ps128(v), _mm256_extractf128_ps(v, 1));
    let s = _mm_add_ps(s, _mm_movehl_ps(s, s));
    _mm_cvtss_f32(_mm_add_ss(s, _mm_movehdup_ps(s)))
}

#[cfg(target_arch = "x86_64")]
simd_block_gram!(
    /// AVX-512F: 6 × 4 tiles of 16 lanes (24 accumulators + 7 operands of the 32 registers).
    block_gram_avx512, block_gram_avx512_impl, "avx512f", 16, 6, 4,
    __m512, _mm512_setzero_ps, _mm512_load_ps, _mm512_fmadd_ps, _mm512_reduce_add_ps
);

#[cfg(target_arch = "x86_64")]
simd_block_gram!(
    /// AVX2 + FMA: 3 × 4 tiles of 8 lanes (12 accumulators + 4 operands = the 16 registers).
    /// (The generic 4 × 4 × 16-lane tile needs 32 accumulator registers: compiled for AVX2 it
    /// was not vectorised at all and ran on scalar FMAs.)
    block_gram_avx2, block_gram_avx2_impl, "avx2,fma", 8, 3, 4,
    __m256, _mm256_setzero_ps, _mm256_load_ps, _mm256_fmadd_ps, hsum256
);

fn block_gram_portable(buf: &[f32], n: usize, stride: usize, len: usize, out: &mut [f32]) {
    block_gram::<false>(buf, n, stride, len, out)
}

/// Upper triangle (j ≥ i, and some entries below it inside diagonal tiles) of the block Gram.
#[inline(always)]
fn block_gram<const FMA: bool>(buf: &[f32], n: usize, stride: usize, len: usize, out: &mut [f32]) {
    let body = len - len % LANES;
    let mut i0 = 0;
    while i0 < n {
        let ri = TILE_R.min(n - i0);
        let mut j0 = i0;
        while j0 < n {
            let cj = TILE_C.min(n - j0);
            if ri == TILE_R && cj == TILE_C {
                let t = tile::<FMA>(buf, stride, i0, j0, body);
                for r in 0..TILE_R {
                    for c in 0..TILE_C {
                        let mut s = t[r][c];
                        let a = &buf[(i0 + r) * stride..];
                        let b = &buf[(j0 + c) * stride..];
                        for k in body..len {
                            s += a[k] * b[k];
                        }
                        out[(i0 + r) * n + j0 + c] = s;
                    }
                }
            } else {
                for r in 0..ri {
                    for c in 0..cj {
                        let a = &buf[(i0 + r) * stride..(i0 + r) * stride + len];
                        let b = &buf[(j0 + c) * stride..(j0 + c) * stride + len];
                        out[(i0 + r) * n + j0 + c] = dot_lanes::<FMA>(a, b);
                    }
                }
            }
            j0 += TILE_C;
        }
        i0 += TILE_R;
    }
}

/// `a·b + c`, fused where the CPU path was compiled with FMA.
#[inline(always)]
pub(crate) fn fmadd<const FMA: bool>(a: f32, b: f32, c: f32) -> f32 {
    if FMA {
        a.mul_add(b, c)
    } else {
        a * b + c
    }
}

/// A TILE_R × TILE_C block of dot products over the first `body` (multiple of LANES) values.
#[inline(always)]
fn tile<const FMA: bool>(
    buf: &[f32],
    stride: usize,
    i0: usize,
    j0: usize,
    body: usize,
) -> [[f32; TILE_C]; TILE_R] {
    let mut acc = [[[0.0f32; LANES]; TILE_C]; TILE_R];
    let rows: [&[f32]; TILE_R] =
        std::array::from_fn(|r| &buf[(i0 + r) * stride..(i0 + r) * stride + body]);
    let cols: [&[f32]; TILE_C] =
        std::array::from_fn(|c| &buf[(j0 + c) * stride..(j0 + c) * stride + body]);
    let mut k = 0;
    while k < body {
        let a: [&[f32; LANES]; TILE_R] =
            std::array::from_fn(|r| rows[r][k..k + LANES].try_into().unwrap());
        let b: [&[f32; LANES]; TILE_C] =
            std::array::from_fn(|c| cols[c][k..k + LANES].try_into().unwrap());
        for r in 0..TILE_R {
            for c in 0..TILE_C {
                for l in 0..LANES {
                    acc[r][c][l] = fmadd::<FMA>(a[r][l], b[c][l], acc[r][c][l]);
                }
            }
        }
        k += LANES;
    }
    let mut out = [[0.0f32; TILE_C]; TILE_R];
    for r in 0..TILE_R {
        for c in 0..TILE_C {
            out[r][c] = acc[r][c].iter().sum();
        }
    }
    out
}

/// The dot product of two `f32` slices over their common length, summed in independent lanes
/// (so that it vectorizes; the order of summation differs from a plain loop's).
///
/// ```
/// let a = [1.0f32; 45];
/// let b: Vec<f32> = (0..45).map(|i| i as f32).collect();
/// assert_eq!(reduce::dot(&a, &b), 990.0);
/// ```
pub fn dot(a: &[f32], b: &[f32]) -> f32 {
    let n = a.len().min(b.len());
    dot_lanes::<false>(&a[..n], &b[..n])
}

/// The lane-wise dot product, with a fused or a plain multiply-add.
#[inline(always)]
pub(crate) fn dot_lanes<const FMA: bool>(a: &[f32], b: &[f32]) -> f32 {
    let mut acc = [0.0f32; LANES];
    let mut ca = a.chunks_exact(LANES);
    let mut cb = b.chunks_exact(LANES);
    for (x, y) in (&mut ca).zip(&mut cb) {
        for l in 0..LANES {
            acc[l] = fmadd::<FMA>(x[l], y[l], acc[l]);
        }
    }
    let mut s: f32 = acc.iter().sum();
    for (x, y) in ca.remainder().iter().zip(cb.remainder()) {
        s += x * y;
    }
    s
}

/// Column means of a row-major `n × dim` matrix, accumulated in `f64`, returned as `f32`.
pub fn column_means(data: &[f32], n: usize, dim: usize) -> Result<Vec<f32>> {
    ReduceError::check_size("data length (n × dim)", n * dim, data.len())?;
    if n == 0 {
        return Err(ReduceError::NotEnoughData("mean of zero rows".into()));
    }
    let mut mean = vec![0.0f32; dim];
    mean.par_chunks_mut(BLOCK).enumerate().for_each(|(b, out)| {
        let c0 = b * BLOCK;
        let mut acc = vec![0.0f64; out.len()];
        for r in 0..n {
            for (a, v) in acc
                .iter_mut()
                .zip(&data[r * dim + c0..r * dim + c0 + out.len()])
            {
                *a += *v as f64;
            }
        }
        for (o, a) in out.iter_mut().zip(&acc) {
            *o = (*a / n as f64) as f32;
        }
    });
    Ok(mean)
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{Rng, SeedableRng};

    #[test]
    fn the_lane_wise_dot_is_the_dot_product_at_every_length() {
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(17);
        for n in 0..80 {
            let a: Vec<f32> = (0..n).map(|_| rng.gen_range(-1.0..1.0)).collect();
            let b: Vec<f32> = (0..n + 3).map(|_| rng.gen_range(-1.0..1.0)).collect();
            let exact: f64 = a.iter().zip(&b).map(|(x, y)| *x as f64 * *y as f64).sum();
            let scale: f64 = a.iter().zip(&b).map(|(x, y)| (*x * *y).abs() as f64).sum();
            let got = dot(&a, &b) as f64;
            assert!(
                (got - exact).abs() <= 1e-6 * scale.max(1e-30),
                "n = {n}: {got} against {exact}"
            );
            assert_eq!(dot(&b, &a), dot(&a, &b[..n]), "the common length is used");
        }
    }

    fn naive(data: &[f32], n: usize, dim: usize, mean: Option<&[f32]>) -> DMatrix<f64> {
        DMatrix::from_fn(n, n, |i, j| {
            (0..dim)
                .map(|d| {
                    let m = mean.map_or(0.0, |m| m[d] as f64);
                    (data[i * dim + d] as f64 - m) * (data[j * dim + d] as f64 - m)
                })
                .sum()
        })
    }

    #[test]
    fn matches_naive_f64_product_for_awkward_sizes() {
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(7);
        // n not a multiple of the tile, dim not a multiple of BLOCK or LANES.
        for &(n, dim) in &[
            (1usize, 5usize),
            (7, 1300),
            (13, 2 * GRAM_BLOCK + 37),
            (9, 33),
        ] {
            let data: Vec<f32> = (0..n * dim).map(|_| rng.gen_range(-3.0..3.0)).collect();
            let mean = column_means(&data, n, dim).unwrap();
            for m in [None, Some(mean.as_slice())] {
                let g = gram_matrix(&data, n, dim, m).unwrap();
                let r = naive(&data, n, dim, m);
                let scale = r.amax().max(1.0);
                assert!((g.clone() - &r).amax() / scale < 1e-5, "n={n} dim={dim}");
                assert_eq!(g, g.transpose());
            }
        }
    }

    #[test]
    fn cross_gram_matches_the_naive_product_and_the_gram_of_one_set() {
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(11);
        for &(m, n, dim) in &[
            (1usize, 1usize, 3usize),
            (7, 5, 1300),
            (3, 10, 2 * GRAM_BLOCK + 9),
            // a tall product (the shapes of a power step): the blocked product
            (BLOCKED_ROWS + 17, 5, GRAM_BLOCK + 33),
        ] {
            let a: Vec<f32> = (0..m * dim).map(|_| rng.gen_range(-3.0..3.0)).collect();
            let b: Vec<f32> = (0..n * dim).map(|_| rng.gen_range(-3.0..3.0)).collect();
            let g = cross_gram_matrix(&a, m, &b, n, dim).unwrap();
            let r = DMatrix::from_fn(m, n, |i, j| {
                (0..dim)
                    .map(|d| a[i * dim + d] as f64 * b[j * dim + d] as f64)
                    .sum::<f64>()
            });
            let scale = r.amax().max(1.0);
            assert!((g - &r).amax() / scale < 1e-5, "m={m} n={n} dim={dim}");
            // a against itself is the Gram matrix
            let s = cross_gram_matrix(&a, m, &a, m, dim).unwrap();
            let full = gram_matrix(&a, m, dim, None).unwrap();
            assert!((s - &full).amax() / full.amax().max(1.0) < 1e-5);
        }
        assert!(cross_gram_matrix(&[1.0; 4], 2, &[1.0; 3], 2, 2).is_err());
    }

    #[test]
    fn a_gram_of_many_rows_takes_the_blocked_product_and_matches_the_naive_one() {
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(12);
        // A Gram of many rows.
        let (m, dim) = (BLOCKED_ROWS + 17, GRAM_BLOCK + 33);
        assert_eq!(GramKernel::for_rows(m), GramKernel::Blocked);
        let a: Vec<f32> = (0..m * dim).map(|_| rng.gen_range(-3.0..3.0)).collect();
        let mean = column_means(&a, m, dim).unwrap();
        for mu in [None, Some(mean.as_slice())] {
            let g = gram_matrix(&a, m, dim, mu).unwrap();
            let r = naive(&a, m, dim, mu);
            assert!((g.clone() - &r).amax() / r.amax() < 1e-5);
            assert_eq!(g, g.transpose());
        }
        // Summing the lower triangles of two panels gives the Gram of their union.
        let split = 700;
        let left: Vec<f32> = a.chunks(dim).flat_map(|r| r[..split].to_vec()).collect();
        let right: Vec<f32> = a.chunks(dim).flat_map(|r| r[split..].to_vec()).collect();
        let mut lower = vec![0.0f64; m * m];
        accumulate_gram_lower(&left, m, split, &mut lower).unwrap();
        accumulate_gram_lower(&right, m, dim - split, &mut lower).unwrap();
        let r = naive(&a, m, dim, None);
        let tol = 1e-5 * r.amax();
        for i in 0..m {
            for j in 0..=i {
                assert!((lower[i * m + j] - r[(i, j)]).abs() < tol);
            }
            assert!(lower[i * m + i + 1..(i + 1) * m].iter().all(|&v| v == 0.0));
        }
        assert!(accumulate_gram_lower(&left, m, split + 1, &mut lower).is_err());
    }

    #[test]
    fn every_available_kernel_agrees_with_the_portable_one() {
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(9);
        assert!(GramKernel::detect().is_available());
        for &(n, dim) in &[
            (96usize, 2 * GRAM_BLOCK + 101),
            (13, GRAM_BLOCK - 3),
            (5, 7),
        ] {
            let data: Vec<f32> = (0..n * dim).map(|_| rng.gen_range(-2.0..2.0)).collect();
            let mean = column_means(&data, n, dim).unwrap();
            for m in [None, Some(mean.as_slice())] {
                let p = gram_matrix_with(&data, n, dim, m, GramKernel::Portable).unwrap();
                for k in [GramKernel::Avx2, GramKernel::Avx512, GramKernel::Blocked] {
                    if !k.is_available() {
                        assert!(gram_matrix_with(&data, n, dim, m, k).is_err());
                        continue;
                    }
                    let g = gram_matrix_with(&data, n, dim, m, k).unwrap();
                    let scale = p.amax().max(1.0);
                    assert!((g - &p).amax() / scale < 1e-5, "{k:?} n={n} dim={dim}");
                }
            }
        }
    }

    #[test]
    fn centred_gram_rows_sum_to_zero() {
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(8);
        let (n, dim) = (10, 3000);
        let data: Vec<f32> = (0..n * dim).map(|_| rng.gen_range(0.0..5.0)).collect();
        let mean = column_means(&data, n, dim).unwrap();
        let g = gram_matrix(&data, n, dim, Some(&mean)).unwrap();
        for i in 0..n {
            let s: f64 = g.row(i).iter().sum();
            assert!(s.abs() < 1e-3 * g[(i, i)], "row {i} sums to {s}");
        }
    }

    #[test]
    fn rejects_wrong_lengths() {
        assert!(gram_matrix(&[0.0; 5], 2, 3, None).is_err());
        assert!(gram_matrix(&[0.0; 6], 2, 3, Some(&[0.0; 2])).is_err());
    }
}
