//! Out-of-core PCA (documented on [`fit`]).

use std::ops::Range;
use std::time::Instant;

use faer::linalg::matmul::matmul;
use faer::{Accum, Mat, MatMut, MatRef, Par, Side};
use nalgebra::DMatrix;
use rayon::prelude::*;

use crate::error::{ReduceError, Result};
use crate::gram::column_means;
use crate::pca::{Pca, RELATIVE_EIGEN_TOLERANCE};

/// An error of a [`ColumnPanels`] source (e.g. of the store it reads).
pub type SourceError = Box<dyn std::error::Error + Send + Sync>;

/// A data matrix of `rows()` vectors of length `dim()`, readable in panels of columns.
pub trait ColumnPanels: Sync {
    /// Number of vectors (materials) `N`.
    fn rows(&self) -> usize;
    /// Vector length `D`.
    fn dim(&self) -> usize;
    /// Panels start at multiples of this many columns and have a width that is a multiple of
    /// it (except the last): the source's natural block, e.g. a store's chunk width.
    fn column_block(&self) -> usize {
        1
    }
    /// Bytes a read of `width` columns needs besides the output (decoding buffers).
    fn read_overhead(&self, width: usize) -> usize {
        let _ = width;
        0
    }
    /// Writes columns `cols` of every vector into `out` (row-major `N × cols.len()`).
    fn read_columns(
        &self,
        cols: Range<usize>,
        out: &mut [f32],
    ) -> std::result::Result<(), SourceError>;
}

/// A row-major in-memory matrix as a [`ColumnPanels`] source (for small corpora and tests).
#[derive(Debug, Clone, Copy)]
pub struct InMemory<'a> {
    data: &'a [f32],
    n: usize,
    dim: usize,
}

impl<'a> InMemory<'a> {
    /// `n` row-major vectors of length `dim`.
    pub fn new(data: &'a [f32], n: usize, dim: usize) -> Result<Self> {
        ReduceError::check_size("in-memory panels (n × dim)", n * dim, data.len())?;
        Ok(InMemory { data, n, dim })
    }
}

impl ColumnPanels for InMemory<'_> {
    fn rows(&self) -> usize {
        self.n
    }
    fn dim(&self) -> usize {
        self.dim
    }
    fn read_columns(
        &self,
        cols: Range<usize>,
        out: &mut [f32],
    ) -> std::result::Result<(), SourceError> {
        let w = cols.len();
        for (i, o) in out.chunks_exact_mut(w).enumerate() {
            o.copy_from_slice(&self.data[i * self.dim + cols.start..i * self.dim + cols.end]);
        }
        Ok(())
    }
}

/// How the components are computed (see [`fit`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum PcaMethod {
    /// The `N × N` Gram matrix: exact, two passes, `O(N²)` memory.
    Gram,
    /// Randomized range finder with `power_iterations` power iterations and `oversampling`
    /// extra sketch columns: `power_iterations + 2` passes.
    Randomized {
        /// Extra columns `p` of the sketch beyond the `k` wanted.
        oversampling: usize,
        /// Power iterations `q`.
        power_iterations: usize,
        /// Seed of the Gaussian test matrix.
        seed: u64,
    },
}

impl PcaMethod {
    /// Randomized with `p = 10`, `q = 2`, seed 0.
    pub const RANDOMIZED: PcaMethod = PcaMethod::Randomized {
        oversampling: 10,
        power_iterations: 2,
        seed: 0,
    };
}

/// Options of [`fit`].
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct OocOptions {
    /// Components wanted `k`.
    pub components: usize,
    /// The method.
    pub method: PcaMethod,
    /// Peak bytes this computation may hold (panels in flight, matrices, the basis).
    pub memory_budget: usize,
}

/// What a run of [`fit`] did.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct OocStats {
    /// Passes over the data.
    pub passes: usize,
    /// Panel width (columns) used.
    pub panel_width: usize,
    /// Seconds the reader thread spent reading panels (summed over passes).
    pub read_seconds: f64,
    /// Seconds spent in the arithmetic on panels (summed over passes).
    pub compute_seconds: f64,
    /// Values read (N × D per pass).
    pub values_read: u64,
    /// Bytes the run planned to hold at its peak (≤ the budget).
    pub planned_bytes: usize,
}

///  Out-of-core PCA: the corpus is streamed from a store in panels of bins, never resident
///  (thesis §4.1; the same model as [`crate::Pca`]).
///
///  A source of data implements [`ColumnPanels`]: it hands out *panels*, all `N` materials
///  over a range of bins (row-major `N × w`). Every panel holds all materials of its bins, so
///  its column means — and therefore the exact mean-centring of eq. 4.1 — are known from the
///  panel alone; the mean vector is formed in the first pass and reused.
///
///  Two methods, both returning a [`Pca`]:
///
///  * [`PcaMethod::Gram`]: the `N × N` centred Gram matrix `B = Yᵀ Y` accumulated panel by panel
///    (its lower triangle, in `f64`) with the kernels of [`crate::gram_matrix`], decomposed, and the
///    components `U = Y V Λ^{-1/2}` formed in a second pass (eqs. 4.1–4.2). Two passes; exact
///    (the same arithmetic as the in-memory PCA). Memory `O(N²)`: `12 N²` bytes while summing
///    (the sums and one block product), `32 N²` while decomposing (3.2 GB at `N = 10,000`).
///  * [`PcaMethod::Randomized`]: the randomized range finder of Halko, Martinsson & Tropp (2011)
///    with `q` power iterations for the leading `k` components at any `N`: a Gaussian sketch
///    `Z = Y Ω` (Ω of `k + p` columns, generated from the seed and the bin index, never
///    stored), then `q` times `Q = orth(Z)`, `Z = Y (Yᵀ Q)`, and a Rayleigh–Ritz step on
///    `Yᵀ Q` (kept resident, `D × (k + p)`): `q + 2` passes. Memory `O(N (k + p) + D (k + p))`.
///
///  Each pass reads the panels on a separate thread, one panel ahead of the arithmetic, and the
///  panel width is chosen so that the peak memory stays within the caller's budget
///  ([`OocOptions::memory_budget`]); [`OocStats`] reports passes, time spent reading and values
///  read.
///
/// Fits PCA to a streamed source; at most `k` components, fewer
/// when the centred data has lower rank.
///
/// # Examples
///
/// ```
/// use reduce::{fit_out_of_core, principal_cosines, InMemory, OocOptions, Pca, PcaMethod};
/// // Twelve vectors of 4,000 values (an in-memory source stands in for a store).
/// let (n, dim) = (12, 4000);
/// let data: Vec<f32> = (0..n * dim)
///     .map(|j| {
///         let (i, d) = ((j / dim) as f32, (j % dim) as f32);
///         (0.001 * d * (i + 1.0)).sin() + 0.3 * (0.0037 * d).cos() * i
///     })
///     .collect();
/// let source = InMemory::new(&data, n, dim).unwrap();
/// // A budget far below the data's 192 KB forces several narrow panels per pass.
/// let options = OocOptions { components: 4, method: PcaMethod::Gram, memory_budget: 96 << 10 };
/// let (streamed, stats) = fit_out_of_core(&source, &options).unwrap();
/// assert_eq!(stats.passes, 2);
/// assert!(stats.panel_width < dim && stats.planned_bytes <= options.memory_budget);
/// assert_eq!(stats.values_read, 2 * (n * dim) as u64);
/// // The Gram method is exact: the same model as the in-memory PCA.
/// let resident = Pca::fit(&data, n, dim, 4).unwrap();
/// for (a, b) in streamed.eigenvalues.iter().zip(&resident.eigenvalues).take(4) {
///     assert!((a - b).abs() <= 1e-6 * b.abs().max(1.0), "{a} vs {b}");
/// }
/// assert!(principal_cosines(&streamed, &resident, 4).unwrap().iter().all(|c| *c > 0.9999));
/// ```
pub fn fit(src: &dyn ColumnPanels, options: &OocOptions) -> Result<(Pca, OocStats)> {
    let (n, dim, k) = (src.rows(), src.dim(), options.components);
    if n < 2 {
        return Err(ReduceError::NotEnoughData(format!(
            "PCA needs at least 2 vectors, got {n}"
        )));
    }
    if k == 0 || dim == 0 {
        return Err(ReduceError::InvalidParameter(
            "number of components and dimension must be positive".into(),
        ));
    }
    match options.method {
        PcaMethod::Gram => fit_gram(src, k, options.memory_budget),
        PcaMethod::Randomized {
            oversampling,
            power_iterations,
            seed,
        } => fit_randomized(
            src,
            k,
            oversampling,
            power_iterations,
            seed,
            options.memory_budget,
        ),
    }
}

/// Plans the panel width: `fixed` bytes are held throughout, each column of a panel costs
/// `per_column` bytes (three panels in flight: being read, queued, being used).
fn plan(
    src: &dyn ColumnPanels,
    fixed: usize,
    per_column: usize,
    budget: usize,
) -> Result<(usize, usize)> {
    let (n, dim, blk) = (src.rows(), src.dim(), src.column_block().max(1));
    let per_col = 3 * n * 4 + per_column;
    let need = |w: usize| fixed + w * per_col + src.read_overhead(w);
    let mut w = budget.saturating_sub(fixed) / per_col;
    w = (w / blk * blk).min(dim.div_ceil(blk) * blk);
    while w >= blk && need(w) > budget {
        w -= blk;
    }
    if w < blk {
        return Err(ReduceError::InvalidParameter(format!(
            "memory budget of {budget} bytes is too small: {} bytes needed for one panel of {blk} columns \
             ({n} rows; a panel holds whole column blocks of the source: raise the budget, or \
             store the data in narrower column blocks)",
            need(blk)
        )));
    }
    Ok((w.min(dim), need(w.min(dim))))
}

/// Reads every panel (on a reader thread, one ahead) and hands it to `f` mean-centred.
/// The first pass (`mean` empty) fills `mean`.
fn pass(
    src: &dyn ColumnPanels,
    width: usize,
    mean: &mut Vec<f32>,
    stats: &mut OocStats,
    mut f: impl FnMut(Range<usize>, &mut [f32]) -> Result<()>,
) -> Result<()> {
    let (n, dim) = (src.rows(), src.dim());
    let first = mean.is_empty();
    if first {
        mean.resize(dim, 0.0);
    }
    let panels: Vec<Range<usize>> = (0..dim)
        .step_by(width)
        .map(|c| c..(c + width).min(dim))
        .collect();
    let (tx, rx) = std::sync::mpsc::sync_channel::<
        std::result::Result<(Range<usize>, Vec<f32>), SourceError>,
    >(1);
    let (back_tx, back_rx) = std::sync::mpsc::channel::<Vec<f32>>();
    let mut read_seconds = 0.0;
    let result = std::thread::scope(|s| -> Result<()> {
        let panels = &panels;
        let reader = s.spawn(move || {
            let mut secs = 0.0;
            for r in panels.iter().cloned() {
                let mut buf = back_rx.try_recv().unwrap_or_default();
                buf.resize(n * r.len(), 0.0);
                let t = Instant::now();
                let res = src.read_columns(r.clone(), &mut buf);
                secs += t.elapsed().as_secs_f64();
                let stop = res.is_err();
                if tx.send(res.map(|()| (r, buf))).is_err() || stop {
                    break;
                }
            }
            secs
        });
        let mut out = Ok(());
        for msg in rx.iter() {
            let (r, mut buf) = match msg {
                Ok(x) => x,
                Err(e) => {
                    out = Err(ReduceError::Numerical(format!("reading panel: {e}")));
                    break;
                }
            };
            let t = Instant::now();
            let w = r.len();
            if first {
                let m = column_means(&buf, n, w)?;
                if m.iter().any(|v| !v.is_finite()) {
                    out = Err(ReduceError::NonFinite("out-of-core PCA input"));
                    break;
                }
                mean[r.clone()].copy_from_slice(&m);
            }
            let m = &mean[r.clone()];
            buf.par_chunks_mut(w).for_each(|row| {
                for (y, mu) in row.iter_mut().zip(m) {
                    *y -= mu;
                }
            });
            if let Err(e) = f(r, &mut buf) {
                out = Err(e);
                break;
            }
            stats.compute_seconds += t.elapsed().as_secs_f64();
            let _ = back_tx.send(buf);
        }
        drop(rx);
        read_seconds = reader.join().unwrap_or(0.0);
        out
    });
    stats.passes += 1;
    stats.read_seconds += read_seconds;
    stats.values_read += (n * dim) as u64;
    tracing::info!(
        pass = stats.passes,
        read_seconds,
        "out-of-core PCA: pass done"
    );
    result
}

fn par() -> Par {
    Par::rayon(0)
}

/// Row-major `rows × cols` `f32` slice as a faer matrix.
fn rm(data: &[f32], rows: usize, cols: usize) -> MatRef<'_, f32> {
    MatRef::from_row_major_slice(data, rows, cols)
}

fn rm_mut(data: &mut [f32], rows: usize, cols: usize) -> MatMut<'_, f32> {
    MatMut::from_row_major_slice_mut(data, rows, cols)
}

/// Symmetric eigen-decomposition with faer (the lower triangle of `m` is read), decreasing
/// order: every eigenvalue, and the eigenvectors of the first `keep` of them (`n × keep`).
fn eigen_desc(m: MatRef<'_, f64>, keep: usize) -> Result<(Vec<f64>, Mat<f64>)> {
    let e = m
        .self_adjoint_eigen(Side::Lower)
        .map_err(|e| ReduceError::Numerical(format!("eigen-decomposition: {e:?}")))?;
    let s = e.S().column_vector();
    let u = e.U();
    let n = m.nrows();
    let mut order: Vec<usize> = (0..n).collect();
    order.sort_by(|&a, &b| s[b].total_cmp(&s[a]));
    let vals = order.iter().map(|&i| s[i].max(0.0)).collect();
    let vecs = Mat::from_fn(n, keep.min(n), |r, c| u[(r, order[c])]);
    Ok((vals, vecs))
}

fn rank_of(eigenvalues: &[f64]) -> Result<usize> {
    let lmax = eigenvalues.first().copied().unwrap_or(0.0);
    if lmax.is_nan() || lmax <= 0.0 {
        return Err(ReduceError::NotEnoughData(
            "all vectors are identical".into(),
        ));
    }
    Ok(eigenvalues
        .iter()
        .filter(|&&l| l > RELATIVE_EIGEN_TOLERANCE * lmax)
        .count())
}

/// Bytes a symmetric eigen-decomposition of an `n × n` matrix holds besides its input: faer's
/// working copy, the eigenvectors and its workspace (measured: see `docs/corpus-store.md`).
fn eigen_bytes(n: usize) -> usize {
    3 * n * n * 8
}

fn fit_gram(src: &dyn ColumnPanels, k: usize, budget: usize) -> Result<(Pca, OocStats)> {
    use crate::gram::{accumulate_gram_lower, GramKernel};
    let (n, dim) = (src.rows(), src.dim());
    // The f64 Gram matrix, the mean and the basis, held throughout; while panels are summed,
    // the block products (one `n × n` f32 matrix for the blocked product, per-thread f32 and
    // f64 accumulators for the register-tiled kernels); then the eigen-decomposition.
    let held = n * n * 8 + dim * 4 + dim * k * 4;
    let summing = match GramKernel::for_rows(n) {
        GramKernel::Blocked => n * n * 4 + n * 1024 * 4,
        _ => rayon::current_num_threads() * n * n * 12,
    };
    let decomposing = held + eigen_bytes(n);
    if decomposing > budget {
        return Err(ReduceError::InvalidParameter(format!(
            "memory budget of {budget} bytes is too small: the eigen-decomposition of the \
             {n} × {n} Gram matrix needs {decomposing} bytes (use the randomized method)"
        )));
    }
    let (width, planned) = plan(src, held + summing, 0, budget)?;
    let mut stats = OocStats {
        panel_width: width,
        planned_bytes: planned.max(decomposing),
        ..OocStats::default()
    };
    let mut mean = Vec::new();
    let mut lower = vec![0.0f64; n * n];
    pass(src, width, &mut mean, &mut stats, |r, panel| {
        accumulate_gram_lower(panel, n, r.len(), &mut lower)
    })?;
    let t = Instant::now();
    let (eigenvalues, v) = eigen_desc(MatRef::from_row_major_slice(&lower, n, n), k)?;
    drop(lower);
    stats.compute_seconds += t.elapsed().as_secs_f64();
    let kk = k.min(rank_of(&eigenvalues)?);
    // u_c = Σ_i V[i][c] / sqrt(λ_c) (y_i − m): coefficients N × K.
    let coef: Vec<f32> = (0..n)
        .flat_map(|i| (0..kk).map(move |c| (i, c)))
        .map(|(i, c)| (v[(i, c)] / eigenvalues[c].sqrt()) as f32)
        .collect();
    let mut basis = vec![0.0f32; dim * kk];
    pass(src, width, &mut mean, &mut stats, |r, panel| {
        let w = r.len();
        let out = rm_mut(&mut basis[r.start * kk..r.end * kk], w, kk);
        matmul(
            out,
            Accum::Replace,
            rm(panel, n, w).transpose(),
            rm(&coef, n, kk),
            1.0f32,
            par(),
        );
        Ok(())
    })?;
    let pca = Pca::assemble(dim, mean, eigenvalues, kk, basis, n, |i, c| v[(i, c)]);
    Ok((pca, stats))
}

/// Standard normal value of the test matrix at (column `d` of the data, sketch column `j`):
/// a counter-based generator, so that any panel can be regenerated without storing Ω.
fn gaussian(seed: u64, d: usize, j: usize) -> f32 {
    fn mix(mut z: u64) -> u64 {
        z = z.wrapping_add(0x9E37_79B9_7F4A_7C15);
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    }
    let h = mix(seed ^ mix((d as u64) << 20 ^ j as u64));
    let u1 = ((h >> 11) as f64 + 0.5) / (1u64 << 53) as f64;
    let u2 = ((mix(h) >> 11) as f64) / (1u64 << 53) as f64;
    ((-2.0 * u1.ln()).sqrt() * (std::f64::consts::TAU * u2).cos()) as f32
}

/// Orthonormal basis of the columns of `z` (thin QR).
fn orth(z: &Mat<f64>) -> Mat<f64> {
    z.qr().compute_thin_Q()
}

fn to_f32_rm(m: &Mat<f64>) -> Vec<f32> {
    let (r, c) = (m.nrows(), m.ncols());
    let mut out = vec![0.0f32; r * c];
    for i in 0..r {
        for j in 0..c {
            out[i * c + j] = m[(i, j)] as f32;
        }
    }
    out
}

fn fit_randomized(
    src: &dyn ColumnPanels,
    k: usize,
    oversampling: usize,
    power_iterations: usize,
    seed: u64,
    budget: usize,
) -> Result<(Pca, OocStats)> {
    let (n, dim) = (src.rows(), src.dim());
    let l = (k + oversampling).min(n).min(dim);
    // Z, Q (f64) and their f32 copies, mean, the resident Yᵀ Q (D × l) and the basis (D × k);
    // per column: Ω and a product row (l f32 each) and a centred-panel × Q scratch.
    let fixed = 4 * n * l * 8 + dim * 4 + dim * l * 4 + dim * k * 4;
    let (width, planned) = plan(src, fixed, 3 * l * 4, budget)?;
    let mut stats = OocStats {
        panel_width: width,
        planned_bytes: planned,
        ..OocStats::default()
    };
    let mut mean = Vec::new();
    let mut acc = vec![0.0f32; n * l];
    let add_into = |z: &mut Mat<f64>, part: &[f32]| {
        for i in 0..n {
            for j in 0..l {
                z[(i, j)] += part[i * l + j] as f64;
            }
        }
    };
    // Sketch Z = Y Ω.
    let mut z = Mat::<f64>::zeros(n, l);
    let mut omega = Vec::new();
    pass(src, width, &mut mean, &mut stats, |r, panel| {
        let w = r.len();
        omega.resize(w * l, 0.0f32);
        omega.par_chunks_mut(l).enumerate().for_each(|(i, row)| {
            for (j, o) in row.iter_mut().enumerate() {
                *o = gaussian(seed, r.start + i, j);
            }
        });
        matmul(
            rm_mut(&mut acc, n, l),
            Accum::Replace,
            rm(panel, n, w),
            rm(&omega, w, l),
            1.0f32,
            par(),
        );
        add_into(&mut z, &acc);
        Ok(())
    })?;
    drop(omega);
    let mut t = Vec::new();
    // Power iterations Z = Y Yᵀ orth(Z).
    for _ in 0..power_iterations {
        let q32 = to_f32_rm(&orth(&z));
        let mut znew = Mat::<f64>::zeros(n, l);
        pass(src, width, &mut mean, &mut stats, |r, panel| {
            let w = r.len();
            t.resize(w * l, 0.0f32);
            let y = rm(panel, n, w);
            matmul(
                rm_mut(&mut t, w, l),
                Accum::Replace,
                y.transpose(),
                rm(&q32, n, l),
                1.0f32,
                par(),
            );
            matmul(
                rm_mut(&mut acc, n, l),
                Accum::Replace,
                y,
                rm(&t, w, l),
                1.0f32,
                par(),
            );
            add_into(&mut znew, &acc);
            Ok(())
        })?;
        z = znew;
    }
    // Rayleigh–Ritz: T = Yᵀ Q (kept), M = Tᵀ T = Qᵀ Y Yᵀ Q.
    let q = orth(&z);
    let q32 = to_f32_rm(&q);
    let mut tall = vec![0.0f32; dim * l];
    let mut mmat = Mat::<f64>::zeros(l, l);
    pass(src, width, &mut mean, &mut stats, |r, panel| {
        let w = r.len();
        let tp = &mut tall[r.start * l..r.end * l];
        matmul(
            rm_mut(tp, w, l),
            Accum::Replace,
            rm(panel, n, w).transpose(),
            rm(&q32, n, l),
            1.0f32,
            par(),
        );
        let tp64 = Mat::from_fn(w, l, |i, j| tp[i * l + j] as f64);
        matmul(
            mmat.as_mut(),
            Accum::Add,
            tp64.transpose(),
            tp64.as_ref(),
            1.0,
            par(),
        );
        Ok(())
    })?;
    let (mu, u) = eigen_desc(mmat.as_ref(), l)?;
    let kk = k.min(rank_of(&mu)?);
    // basis = T U_k Σ⁻¹ (D × k), coords = Q U_k Σ (N × k).
    let coef: Vec<f32> = (0..l)
        .flat_map(|i| (0..kk).map(move |c| (i, c)))
        .map(|(i, c)| (u[(i, c)] / mu[c].sqrt()) as f32)
        .collect();
    let mut basis = vec![0.0f32; dim * kk];
    matmul(
        rm_mut(&mut basis, dim, kk),
        Accum::Replace,
        rm(&tall, dim, l),
        rm(&coef, l, kk),
        1.0f32,
        par(),
    );
    drop(tall);
    let qu = &q * u.as_ref();
    let coords = DMatrix::from_fn(n, kk, |i, c| qu[(i, c)] * mu[c].sqrt());
    Ok((
        Pca {
            dim,
            mean,
            eigenvalues: mu,
            components: kk,
            basis,
            coords,
        },
        stats,
    ))
}

/// Cosines of the principal angles between the spans of the first `k` components of two
/// models (1 = same direction), decreasing; a check that two fits found the same subspace.
pub fn principal_cosines(a: &Pca, b: &Pca, k: usize) -> Result<Vec<f64>> {
    if a.dim != b.dim || k > a.components || k > b.components {
        return Err(ReduceError::InvalidParameter(format!(
            "principal angles of {k} components of models with {} and {} components (dims {}, {})",
            a.components, b.components, a.dim, b.dim
        )));
    }
    // C = U_aᵀ U_b (k × k) in f64, then its singular values.
    let mut c = Mat::<f64>::zeros(k, k);
    for d in 0..a.dim {
        let ra = &a.basis[d * a.components..d * a.components + k];
        let rb = &b.basis[d * b.components..d * b.components + k];
        for i in 0..k {
            for j in 0..k {
                c[(i, j)] += ra[i] as f64 * rb[j] as f64;
            }
        }
    }
    let s = c
        .singular_values()
        .map_err(|e| ReduceError::Numerical(format!("SVD: {e:?}")))?;
    let mut s: Vec<f64> = s.into_iter().map(|x| x.min(1.0)).collect();
    s.sort_by(|x, y| y.total_cmp(x));
    Ok(s)
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{Rng, SeedableRng};

    /// Data with a decaying spectrum: `r` directions with weights 0.8^i, plus noise.
    fn spectral(n: usize, dim: usize, r: usize, seed: u64) -> Vec<f32> {
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed);
        let dirs: Vec<Vec<f32>> = (0..r)
            .map(|_| (0..dim).map(|_| rng.gen_range(-1.0..1.0)).collect())
            .collect();
        let mut data = vec![0.0f32; n * dim];
        for i in 0..n {
            for (c, dir) in dirs.iter().enumerate() {
                let w = rng.gen_range(-1.0f32..1.0) * 0.8f32.powi(c as i32);
                for d in 0..dim {
                    data[i * dim + d] += w * dir[d];
                }
            }
            for d in 0..dim {
                data[i * dim + d] += 3.0 + 1e-4 * rng.gen_range(-1.0f32..1.0);
            }
        }
        data
    }

    struct Chunked<'a>(InMemory<'a>, usize);
    impl ColumnPanels for Chunked<'_> {
        fn rows(&self) -> usize {
            self.0.rows()
        }
        fn dim(&self) -> usize {
            self.0.dim()
        }
        fn column_block(&self) -> usize {
            self.1
        }
        fn read_columns(
            &self,
            cols: Range<usize>,
            out: &mut [f32],
        ) -> std::result::Result<(), SourceError> {
            assert_eq!(cols.start % self.1, 0);
            self.0.read_columns(cols, out)
        }
    }

    #[test]
    fn gram_of_many_materials_sums_blocked_panels_and_matches_the_in_memory_pca() {
        use crate::gram::{GramKernel, BLOCKED_ROWS};
        let (n, dim, k) = (BLOCKED_ROWS + 32, 2100, 5);
        assert_eq!(GramKernel::for_rows(n), GramKernel::Blocked);
        let data = spectral(n, dim, 9, 4);
        let reference = Pca::fit(&data, n, dim, k).unwrap();
        let src = Chunked(InMemory::new(&data, n, dim).unwrap(), 100);
        let budget = n * n * 8
            + dim * 4 * (k + 1)
            + (3 * n * n * 8).max(n * n * 4 + n * 1024 * 4 + 3 * n * 4 * 700);
        let options = OocOptions {
            components: k,
            method: PcaMethod::Gram,
            memory_budget: budget,
        };
        let (g, st) = fit(&src, &options).unwrap();
        assert!(st.panel_width < dim, "{st:?}");
        assert!(st.planned_bytes <= budget);
        for (a, b) in g.eigenvalues.iter().zip(&reference.eigenvalues).take(k) {
            assert!((a - b).abs() <= 1e-6 * b, "{a} vs {b}");
        }
        let cos = principal_cosines(&g, &reference, k).unwrap();
        assert!(cos[k - 1] > 1.0 - 1e-6, "{cos:?}");
        // a budget that holds the sums but not the eigen-decomposition is refused up front
        let small = OocOptions {
            memory_budget: n * n * 8 + dim * 4 * (k + 1) + 2 * n * n * 8,
            ..options
        };
        let err = fit(&src, &small).unwrap_err().to_string();
        assert!(err.contains("eigen-decomposition"), "{err}");
    }

    #[test]
    fn gram_and_randomized_match_the_in_memory_pca() {
        let (n, dim, k) = (40, 3001, 6);
        let data = spectral(n, dim, 12, 3);
        let reference = Pca::fit(&data, n, dim, k).unwrap();
        let src = Chunked(InMemory::new(&data, n, dim).unwrap(), 100);
        // a budget that forces several panels
        let budget = 3 * n * n * 8
            + rayon::current_num_threads() * n * n * 12
            + dim * 4 * (k + 1)
            + 3 * n * 4 * 700;
        let (g, st) = fit(
            &src,
            &OocOptions {
                components: k,
                method: PcaMethod::Gram,
                memory_budget: budget,
            },
        )
        .unwrap();
        assert!(st.panel_width < dim && st.panel_width % 100 == 0, "{st:?}");
        assert!(st.planned_bytes <= budget);
        assert_eq!(st.passes, 2);
        for (a, b) in g.eigenvalues.iter().zip(&reference.eigenvalues).take(k) {
            assert!((a - b).abs() <= 1e-6 * b, "{a} vs {b}");
        }
        assert!((g.mean[17] - reference.mean[17]).abs() < 1e-6);
        let cos = principal_cosines(&g, &reference, k).unwrap();
        assert!(cos[k - 1] > 1.0 - 1e-6, "{cos:?}");
        let big = 4 * n * 20 * 8 + dim * 4 * (1 + 20 + k) + (3 * n * 4 + 3 * 20 * 4) * 800;
        let method = PcaMethod::Randomized {
            oversampling: 14,
            power_iterations: 3,
            seed: 5,
        };
        let (r, st) = fit(
            &src,
            &OocOptions {
                components: k,
                method,
                memory_budget: big,
            },
        )
        .unwrap();
        assert_eq!(st.passes, 5);
        for (a, b) in r.eigenvalues.iter().zip(&reference.eigenvalues).take(k) {
            assert!((a - b).abs() <= 1e-4 * b, "{a} vs {b}");
        }
        let cos = principal_cosines(&r, &reference, k).unwrap();
        assert!(cos[k - 1] > 1.0 - 1e-4, "{cos:?}");
        // coordinates reproduce the data: x_i = U_kᵀ (y_i − m)
        let x = r.project(&data[5 * dim..6 * dim], k).unwrap();
        for (c, xc) in x.iter().enumerate() {
            assert!((xc - r.coords[(5, c)]).abs() < 1e-3 * r.eigenvalues[0].sqrt());
        }
    }

    #[test]
    fn too_small_a_budget_is_an_error() {
        let data = spectral(10, 500, 3, 1);
        let src = InMemory::new(&data, 10, 500).unwrap();
        let o = OocOptions {
            components: 2,
            method: PcaMethod::RANDOMIZED,
            memory_budget: 1000,
        };
        assert!(matches!(
            fit(&src, &o),
            Err(ReduceError::InvalidParameter(_))
        ));
    }

    #[test]
    fn the_test_matrix_is_standard_normal() {
        let v: Vec<f64> = (0..20000)
            .map(|i| gaussian(9, i / 7, i % 7) as f64)
            .collect();
        let m = v.iter().sum::<f64>() / v.len() as f64;
        let var = v.iter().map(|x| (x - m) * (x - m)).sum::<f64>() / v.len() as f64;
        assert!(m.abs() < 0.03 && (var - 1.0).abs() < 0.05, "{m} {var}");
        assert_eq!(gaussian(9, 3, 4), gaussian(9, 3, 4));
    }
}
