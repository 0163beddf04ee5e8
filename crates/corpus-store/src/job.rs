//! The corpus jobs behind `gantry corpus pack|synth|info|pca`.

use std::fmt;
use std::path::PathBuf;
use std::time::Instant;

use reduce::{OocOptions, PcaMethod};
use sampling::SampleGrid;
use serde::Serialize;

use crate::error::{Result, StoreError};
use crate::pack::{DecodedSources, MaterialSource, PackProgress};
use crate::store::{bins_per_chunk_for, Verification};
use crate::synth::{SynthOptions, Synthesizer};
use crate::{CorpusStore, FaultKind, StoreOptions, ValueType};

/// A number of bytes written as `4G`, `512M`, `64k` or plain bytes (binary multiples).
///
/// ```
/// use corpus_store::ByteSize;
/// assert_eq!("512M".parse::<ByteSize>().unwrap().0, 512 << 20);
/// assert_eq!("1.5k".parse::<ByteSize>().unwrap().0, 1536);
/// assert!("4Q".parse::<ByteSize>().is_err());
/// ```
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
pub struct ByteSize(pub usize);

impl std::str::FromStr for ByteSize {
    type Err = StoreError;

    fn from_str(s: &str) -> Result<Self> {
        let t = s.trim();
        let (num, mul) = match t.char_indices().last() {
            Some((i, c)) if c.is_ascii_alphabetic() => {
                let m: usize = match c.to_ascii_uppercase() {
                    'K' => 1 << 10,
                    'M' => 1 << 20,
                    'G' => 1 << 30,
                    'T' => 1 << 40,
                    _ => {
                        return Err(StoreError::InvalidParameter(format!(
                            "size {s:?}: unknown unit {c}"
                        )))
                    }
                };
                (&t[..i], m)
            }
            _ => (t, 1),
        };
        let v: f64 = num.trim().parse().map_err(|_| {
            StoreError::InvalidParameter(format!("size {s:?}: expected e.g. 4G, 512M"))
        })?;
        if !(v.is_finite() && v >= 0.0) {
            return Err(StoreError::InvalidParameter(format!(
                "size {s:?}: expected a non-negative size"
            )));
        }
        Ok(ByteSize((v * mul as f64) as usize))
    }
}

/// The layout of a store to write (shared by [`PackJob`] and [`SynthJob`]).
#[derive(Debug, Clone)]
#[cfg_attr(feature = "cli", derive(clap::Args))]
pub struct LayoutOptions {
    /// Output store directory (e.g. corpus.zarr).
    #[cfg_attr(feature = "cli", arg(long))]
    pub out: PathBuf,
    /// Grid: `full` (90×90×180), `quarter` (45×45×90), a stride `S`, or strides `A:B:C`.
    #[cfg_attr(feature = "cli", arg(long, default_value = "full"))]
    pub grid: SampleGrid,
    /// Element type of the stored log values: f16 or f32.
    #[cfg_attr(feature = "cli", arg(long, default_value = "f16"))]
    pub dtype: ValueType,
    /// Materials per chunk.
    #[cfg_attr(feature = "cli", arg(long, default_value_t = 16))]
    pub materials_per_chunk: usize,
    /// Bins per chunk [default: from the number of materials, so that one column of chunks
    /// of all materials takes at most 256 MiB as f32: 65,536 bins up to 1,024 materials,
    /// 4,096 for 10,000].
    #[cfg_attr(feature = "cli", arg(long))]
    pub bins_per_chunk: Option<usize>,
    /// zstd level.
    #[cfg_attr(feature = "cli", arg(long, default_value_t = 3))]
    pub zstd_level: i32,
}

impl LayoutOptions {
    fn store_options(&self, materials: usize) -> StoreOptions {
        StoreOptions {
            value_type: self.dtype,
            materials_per_chunk: self.materials_per_chunk,
            bins_per_chunk: self
                .bins_per_chunk
                .unwrap_or_else(|| bins_per_chunk_for(materials)),
            zstd_level: self.zstd_level,
        }
    }
}

/// Pack materials (NBRDF directories, .binary files, specs, stores) into a Zarr store
/// (resumable: rerun the same command after an interruption).
#[derive(Debug, Clone)]
#[cfg_attr(feature = "cli", derive(clap::Args))]
pub struct PackJob {
    /// Inputs: directories, .binary files, material specs or stores.
    #[cfg_attr(feature = "cli", arg(required = true))]
    pub inputs: Vec<PathBuf>,
    /// Where and how to write.
    #[cfg_attr(feature = "cli", command(flatten))]
    pub layout: LayoutOptions,
}

/// Write a synthetic corpus of N physically valid materials made from measured ones.
///
/// # Examples
///
/// ```
/// use corpus_store::{validity, CorpusStore, LayoutOptions, SynthJob, ValueType, MAX_ALBEDO};
/// use sampling::SampleGrid;
///
/// let dir = tempfile::tempdir().unwrap();
/// let layout = |out: std::path::PathBuf| LayoutOptions {
///     out,
///     grid: SampleGrid::new(15, 15, 30).unwrap(), // a 6 × 6 × 6 subsampling of the MERL grid
///     dtype: ValueType::F32,
///     materials_per_chunk: 2,
///     bins_per_chunk: Some(128),
///     zstd_level: 3,
/// };
/// let job = SynthJob {
///     from: vec!["lambert:kd=0.5".into(), "ggx:alpha=0.1".into(), "ggx:alpha=0.4".into()],
///     n: 5,
///     seed: 3,
///     mix: 2,
///     lobe_probability: 0.5,
///     layout: layout(dir.path().join("synth.zarr")),
/// };
/// let report = job.run(&mut |_| {}).unwrap();
/// assert_eq!((report.materials, report.resumed), (5, 0));
/// // Running it again finds every block complete and writes nothing.
/// assert_eq!(job.run(&mut |_| {}).unwrap().resumed, 5);
/// // Every synthetic material passed the physical checks before it was stored: non-negative,
/// // reciprocal, directional albedo at most MAX_ALBEDO (up to the f32 rounding of the logs).
/// let store = CorpusStore::open_complete(&report.out).unwrap();
/// let rows = store.read_rows(0..5).unwrap();
/// for row in rows.chunks(store.dim()) {
///     let values: Vec<f64> = row.iter().map(|&y| brdf::from_log(y as f64)).collect();
///     let v = validity(&values, store.info().grid).unwrap();
///     assert!(v.min_value > -1e-6 && v.reciprocity < 1e-6, "{v:?}");
///     assert!(v.max_albedo <= MAX_ALBEDO + 1e-4, "{v:?}");
/// }
/// ```
#[derive(Debug, Clone)]
#[cfg_attr(feature = "cli", derive(clap::Args))]
pub struct SynthJob {
    /// Base materials (directories, files, specs), e.g. the MERL weight directory.
    #[cfg_attr(feature = "cli", arg(long, num_args = 1.., required = true))]
    pub from: Vec<PathBuf>,
    /// Number of materials.
    #[cfg_attr(feature = "cli", arg(long))]
    pub n: usize,
    /// Seed.
    #[cfg_attr(feature = "cli", arg(long, default_value_t = 0))]
    pub seed: u64,
    /// Base materials per convex combination.
    #[cfg_attr(feature = "cli", arg(long, default_value_t = 3))]
    pub mix: usize,
    /// Probability of an added GGX lobe.
    #[cfg_attr(feature = "cli", arg(long, default_value_t = 0.5))]
    pub lobe_probability: f64,
    /// Where and how to write.
    #[cfg_attr(feature = "cli", command(flatten))]
    pub layout: LayoutOptions,
}

/// What a pack or synth job wrote.
#[derive(Debug, Clone, Serialize)]
pub struct PackReport {
    /// The store written.
    pub out: PathBuf,
    /// Materials in the store.
    pub materials: usize,
    /// Materials of blocks found complete on disk (a resumed pack).
    pub resumed: usize,
    /// Wall-clock seconds.
    pub seconds: f64,
    /// Values per material.
    pub dim: usize,
    /// Zarr name of the element type.
    pub value_type: String,
    /// Bytes of the values uncompressed.
    pub raw_bytes: u64,
    /// Bytes of the store's files.
    pub disk_bytes: u64,
}

impl fmt::Display for PackReport {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(
            f,
            "packed {} materials ({} resumed from disk) into {} in {:.1} s: {} × {} {}, {:.2} GB raw, {:.2} GB on disk (ratio {:.2})",
            self.materials,
            self.resumed,
            self.out.display(),
            self.seconds,
            self.materials,
            self.dim,
            self.value_type,
            self.raw_bytes as f64 / 1e9,
            self.disk_bytes as f64 / 1e9,
            self.raw_bytes as f64 / self.disk_bytes.max(1) as f64
        )
    }
}

fn pack_source(
    src: &dyn MaterialSource,
    layout: &LayoutOptions,
    progress: &mut dyn FnMut(PackProgress),
) -> Result<PackReport> {
    let t = Instant::now();
    let mut resumed = 0;
    let store = crate::pack::pack(
        src,
        &layout.out,
        layout.store_options(src.len()),
        &mut |p: PackProgress| {
            resumed = p.skipped;
            progress(p)
        },
    )?;
    let info = store.info();
    Ok(PackReport {
        out: layout.out.clone(),
        materials: store.len(),
        resumed,
        seconds: t.elapsed().as_secs_f64(),
        dim: store.dim(),
        value_type: info.value_type.zarr_name().to_string(),
        raw_bytes: info.raw_bytes(),
        disk_bytes: store.bytes_on_disk(),
    })
}

impl PackJob {
    /// Packs the inputs of this job into a store, resuming a pack that was interrupted.
    ///
    /// ```
    /// use corpus_store::{LayoutOptions, PackJob};
    /// let dir = tempfile::tempdir().unwrap();
    /// let job = PackJob {
    ///     inputs: vec!["lambert:kd=0.5".into(), "ggx:alpha=0.2".into()],
    ///     layout: LayoutOptions {
    ///         out: dir.path().join("c.zarr"),
    ///         grid: "15".parse().unwrap(),
    ///         dtype: corpus_store::ValueType::F32,
    ///         materials_per_chunk: 2,
    ///         bins_per_chunk: None,
    ///         zstd_level: 3,
    ///     },
    /// };
    /// let report = job.run(&mut |_| {}).unwrap();
    /// assert_eq!((report.materials, report.resumed), (2, 0));
    /// ```
    pub fn run(&self, progress: &mut dyn FnMut(PackProgress)) -> Result<PackReport> {
        let src = DecodedSources::new(&self.inputs, self.layout.grid)?;
        pack_source(&src, &self.layout, progress)
    }
}

impl SynthJob {
    /// Writes the synthetic corpus of this job (resumable like [`PackJob::run`]).
    pub fn run(&self, progress: &mut dyn FnMut(PackProgress)) -> Result<PackReport> {
        let sources = brdf::sources(&self.from)?;
        let opts = SynthOptions {
            n: self.n,
            seed: self.seed,
            mix: self.mix,
            lobe_probability: self.lobe_probability,
        };
        tracing::info!("decoding {} base materials on the grid …", sources.len());
        let synth = Synthesizer::from_sources(&sources, self.layout.grid, opts)?;
        pack_source(&synth, &self.layout, progress)
    }
}

/// Summarise a store: materials, grid, layout, compression, completeness.
///
/// # Examples
///
/// ```
/// use corpus_store::{InfoJob, LayoutOptions, PackJob, ValueType};
/// use sampling::SampleGrid;
///
/// let dir = tempfile::tempdir().unwrap();
/// let layout = |out: std::path::PathBuf| LayoutOptions {
///     out,
///     grid: SampleGrid::new(15, 15, 30).unwrap(), // a 6 × 6 × 6 subsampling of the MERL grid
///     dtype: ValueType::F32,
///     materials_per_chunk: 2,
///     bins_per_chunk: Some(128),
///     zstd_level: 3,
/// };
/// let out = dir.path().join("corpus.zarr");
/// let inputs = vec!["lambert:kd=0.5".into(), "ggx:alpha=0.2,kd=0.1".into(), "lambert:kd=0.2".into()];
/// PackJob { inputs, layout: layout(out.clone()) }.run(&mut |_| {}).unwrap();
///
/// let info = InfoJob { store: out.clone(), names: true, quick: false }.run(&|_, _| {}).unwrap();
/// assert_eq!(info.names, ["lambert:kd=0.5", "ggx:alpha=0.2,kd=0.1", "lambert:kd=0.2"]);
/// assert_eq!((info.shape, info.strides), ((6, 6, 6), (15, 15, 30)));
/// assert_eq!((info.dim, info.value_type.as_str()), (3 * 216, "float32"));
/// assert_eq!(info.chunk, (2, 128));
/// assert_eq!(info.raw_bytes, 3 * 3 * 216 * 4);
/// assert!(info.is_complete() && info.verification.as_ref().unwrap().is_intact());
/// // A chunk that goes missing is reported.
/// std::fs::remove_file(out.join("values/c/1/0")).unwrap();
/// let quick = InfoJob { store: out, names: false, quick: true }.run(&|_, _| {}).unwrap();
/// assert_eq!(quick.missing_chunks, 1);
/// assert!(!quick.is_complete());
/// ```
#[derive(Debug, Clone)]
#[cfg_attr(feature = "cli", derive(clap::Args))]
pub struct InfoJob {
    /// The store.
    pub store: PathBuf,
    /// Also list every material name.
    #[cfg_attr(feature = "cli", arg(long))]
    pub names: bool,
    /// Only look for missing chunk files instead of reading and checking every chunk.
    #[cfg_attr(feature = "cli", arg(long))]
    pub quick: bool,
}

/// A store's summary ([`InfoJob::run`]).
#[derive(Debug, Clone, Serialize)]
pub struct InfoReport {
    /// The store.
    pub store: PathBuf,
    /// Material names, in row order.
    pub names: Vec<String>,
    /// Whether the display lists every name (otherwise the first five).
    pub list_names: bool,
    /// Grid shape (θh, θd, φd).
    pub shape: (usize, usize, usize),
    /// Grid strides (θh, θd, φd).
    pub strides: (usize, usize, usize),
    /// Values per material.
    pub dim: usize,
    /// Zarr name of the element type.
    pub value_type: String,
    /// Floor of the log transform.
    pub log_floor: f64,
    /// Chunk shape (materials, bins).
    pub chunk: (usize, usize),
    /// Chunks along (materials, bins).
    pub chunk_grid: (usize, usize),
    /// Whether chunks carry crc32c checksums.
    pub checksums: bool,
    /// Bytes of the values uncompressed.
    pub raw_bytes: u64,
    /// Bytes of the store's files.
    pub disk_bytes: u64,
    /// Chunk files missing (from a file listing).
    pub missing_chunks: usize,
    /// Every chunk read back and checked (absent with `quick`).
    pub verification: Option<Verification>,
}

impl InfoReport {
    /// Whether the store is complete: every chunk present (and, when verified, decodes).
    pub fn is_complete(&self) -> bool {
        match &self.verification {
            Some(v) => v.is_intact(),
            None => self.missing_chunks == 0,
        }
    }
}

impl fmt::Display for InfoReport {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let (th, td, pd) = self.shape;
        let (cm, cb) = self.chunk_grid;
        writeln!(f, "store        {}", self.store.display())?;
        writeln!(f, "materials    {}", self.names.len())?;
        writeln!(
            f,
            "grid         {th} × {td} × {pd} × 3 (strides {}:{}:{}), D = {}",
            self.strides.0, self.strides.1, self.strides.2, self.dim
        )?;
        writeln!(
            f,
            "values       {} of ln(max(f,0) + {})",
            self.value_type, self.log_floor
        )?;
        writeln!(
            f,
            "chunks       {} materials × {} bins ({cm} × {cb} chunks), zstd{}",
            self.chunk.0,
            self.chunk.1,
            if self.checksums { " + crc32c" } else { "" }
        )?;
        writeln!(
            f,
            "size         {:.3} GB raw, {:.3} GB on disk (ratio {:.2})",
            self.raw_bytes as f64 / 1e9,
            self.disk_bytes as f64 / 1e9,
            self.raw_bytes as f64 / self.disk_bytes.max(1) as f64
        )?;
        match &self.verification {
            None if self.missing_chunks == 0 => {
                writeln!(f, "complete     yes (files present; not verified: --quick)")?
            }
            None => writeln!(
                f,
                "complete     no: {} of {} chunks missing (resume the pack)",
                self.missing_chunks,
                cm * cb
            )?,
            Some(v) => {
                let sums = if v.checksummed {
                    "crc32c checksums verified"
                } else {
                    "no checksums in this store (format 1): decoded only"
                };
                if v.is_intact() {
                    writeln!(
                        f,
                        "complete     yes: all {} chunks read back ({sums})",
                        v.chunks
                    )?;
                } else {
                    writeln!(
                        f,
                        "complete     no: {} missing, {} damaged, {} unreadable of {} chunks ({sums})",
                        v.count(FaultKind::Missing),
                        v.count(FaultKind::Damaged),
                        v.count(FaultKind::Unreadable),
                        v.chunks
                    )?;
                    for c in &v.faults {
                        writeln!(
                            f,
                            "  chunk {}/{}: {:?}: {}",
                            c.chunk.0, c.chunk.1, c.kind, c.detail
                        )?;
                    }
                }
            }
        }
        if self.list_names {
            for (i, n) in self.names.iter().enumerate() {
                if i > 0 {
                    writeln!(f)?;
                }
                write!(f, "{n}")?;
            }
            Ok(())
        } else {
            let shown: Vec<&str> = self.names.iter().take(5).map(String::as_str).collect();
            write!(
                f,
                "names        {}{}",
                shown.join(", "),
                if self.names.len() > 5 { ", …" } else { "" }
            )
        }
    }
}

impl InfoJob {
    /// Summarises the store of this job; unless `self.quick`, reads every chunk back (`progress` gets
    /// the material blocks done and their number).
    pub fn run(&self, progress: &(dyn Fn(usize, usize) + Sync)) -> Result<InfoReport> {
        let s = CorpusStore::open(&self.store)?;
        let i = s.info();
        let blocks = i.chunk_grid().0;
        let verification = (!self.quick).then(|| s.verify(&|done| progress(done, blocks)));
        Ok(InfoReport {
            store: self.store.clone(),
            names: i.names.clone(),
            list_names: self.names,
            shape: i.grid.shape(),
            strides: (i.grid.theta_h_step, i.grid.theta_d_step, i.grid.phi_d_step),
            dim: i.dim(),
            value_type: i.value_type.zarr_name().to_string(),
            log_floor: i.log_floor,
            chunk: i.chunk,
            chunk_grid: i.chunk_grid(),
            checksums: s.has_checksums(),
            raw_bytes: i.raw_bytes(),
            disk_bytes: s.bytes_on_disk(),
            missing_chunks: s.missing_chunks(),
            verification,
        })
    }
}

/// PCA of a store out of core, within a memory budget; writes a model file.
///
/// # Examples
///
/// ```
/// use corpus_store::{ByteSize, CorpusStore, LayoutOptions, PackJob, PcaJob, ValueType};
/// use sampling::SampleGrid;
///
/// let dir = tempfile::tempdir().unwrap();
/// let layout = |out: std::path::PathBuf| LayoutOptions {
///     out,
///     grid: SampleGrid::new(15, 15, 30).unwrap(), // a 6 × 6 × 6 subsampling of the MERL grid
///     dtype: ValueType::F32,
///     materials_per_chunk: 2,
///     bins_per_chunk: Some(128),
///     zstd_level: 3,
/// };
/// let store = dir.path().join("corpus.zarr");
/// let inputs = vec!["lambert:kd=0.5".into(), "ggx:alpha=0.2,kd=0.1".into(), "lambert:kd=0.2".into()];
/// PackJob { inputs, layout: layout(store.clone()) }.run(&mut |_| {}).unwrap();
///
/// let job = PcaJob {
///     corpus: store.clone(),
///     components: 2,
///     memory_budget: ByteSize(64 << 20),
///     method: "gram".into(),
///     power_iterations: 2,
///     oversampling: 10,
///     seed: 0,
///     out: dir.path().join("model.bin"),
///     stats: None,
///     basis_npy: None,
///     measure_read: false,
/// };
/// let report = job.run().unwrap();
/// assert_eq!((report.materials, report.components), (3, 2));
/// // Three materials span at most two directions about their mean: two components keep it all.
/// assert!(report.kept_variance > 1.0 - 1e-6, "{}", report.kept_variance);
/// // So the model file reproduces every stored row from its coordinates.
/// let model = reduce::Model::load(&job.out).unwrap();
/// let rows = CorpusStore::open(&store).unwrap().read_rows(0..3).unwrap();
/// let dim = rows.len() / 3;
/// for i in 0..3 {
///     let c: Vec<f64> = model.pca.coords.row(i).iter().copied().collect();
///     let back = model.pca.reconstruct(&c).unwrap();
///     let row = &rows[i * dim..(i + 1) * dim];
///     assert!(back.iter().zip(row).all(|(a, b)| (a - b).abs() < 1e-3));
/// }
/// ```
#[derive(Debug, Clone)]
#[cfg_attr(feature = "cli", derive(clap::Args))]
pub struct PcaJob {
    /// The store.
    #[cfg_attr(feature = "cli", arg(long))]
    pub corpus: PathBuf,
    /// Components kept.
    #[cfg_attr(feature = "cli", arg(long, default_value_t = 45))]
    pub components: usize,
    /// Peak memory of the computation, e.g. 2G, 512M (panels, matrices, the basis).
    #[cfg_attr(feature = "cli", arg(long, default_value = "4G"))]
    pub memory_budget: ByteSize,
    /// `gram` (exact, O(N²) memory), `randomized`, or `auto` (Gram up to 2,000 materials).
    #[cfg_attr(feature = "cli", arg(long, default_value = "auto"))]
    pub method: String,
    /// Power iterations of the randomized method.
    #[cfg_attr(feature = "cli", arg(long, default_value_t = 2))]
    pub power_iterations: usize,
    /// Oversampling of the randomized method.
    #[cfg_attr(feature = "cli", arg(long, default_value_t = 10))]
    pub oversampling: usize,
    /// Seed of the randomized method.
    #[cfg_attr(feature = "cli", arg(long, default_value_t = 0))]
    pub seed: u64,
    /// Output model file (the `reduce` model format, without chart).
    #[cfg_attr(feature = "cli", arg(long))]
    pub out: PathBuf,
    /// Also write the run's figures (time, memory, passes) as JSON.
    #[cfg_attr(feature = "cli", arg(long))]
    pub stats: Option<PathBuf>,
    /// Also write the components as a `.npy` file (D × K float32, for other tools).
    #[cfg_attr(feature = "cli", arg(long))]
    pub basis_npy: Option<PathBuf>,
    /// Before the PCA, read the whole store once without arithmetic and report the time (the
    /// limit of a streamed computation, measured in the same run).
    #[cfg_attr(feature = "cli", arg(long))]
    pub measure_read: bool,
}

/// The figures of a [`PcaJob::run`] (also the `--stats` JSON).
#[derive(Debug, Clone, Serialize)]
pub struct PcaReport {
    /// The store.
    pub store: String,
    /// Materials.
    pub materials: usize,
    /// Values per material.
    pub dim: usize,
    /// Zarr name of the element type.
    pub value_type: String,
    /// Bytes of the store's files.
    pub bytes_on_disk: u64,
    /// The method used.
    pub method: String,
    /// Components kept.
    pub components: usize,
    /// The memory budget, bytes.
    pub memory_budget: usize,
    /// Bytes the run planned to hold at its peak.
    pub planned_bytes: usize,
    /// Peak resident memory of the process, bytes (where the system tells).
    pub peak_rss: Option<u64>,
    /// Wall-clock seconds of the PCA.
    pub wall_seconds: f64,
    /// CPU seconds of the PCA (where the system tells).
    pub cpu_seconds: Option<f64>,
    /// Passes over the store.
    pub passes: usize,
    /// Seconds spent reading panels.
    pub read_seconds: f64,
    /// Seconds spent in arithmetic.
    pub compute_seconds: f64,
    /// Panel width, bins.
    pub panel_width: usize,
    /// Seconds of one plain read of the store (`measure_read`).
    pub read_once_seconds: Option<f64>,
    /// CPU seconds of that read.
    pub read_once_cpu_seconds: Option<f64>,
    /// The kept eigenvalues.
    pub eigenvalues: Vec<f64>,
    /// The first five eigenvalues found (may go beyond the kept ones).
    pub leading_eigenvalues: Vec<f64>,
    /// Fraction of the variance found that the kept components hold.
    pub kept_variance: f64,
}

impl fmt::Display for PcaReport {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let gb = |b: f64| b / 1e9;
        let secs = |s: Option<f64>| s.map_or("?".into(), |c| format!("{c:.1} s"));
        if let Some(t) = self.read_once_seconds {
            let decoded = gb((self.materials * self.dim * 4) as f64);
            writeln!(
                f,
                "read the store once in {t:.1} s wall (CPU {}): {:.2} GB on disk, {decoded:.2} GB of values decoded ({:.2} GB/s)",
                secs(self.read_once_cpu_seconds),
                gb(self.bytes_on_disk as f64),
                decoded / t
            )?;
        }
        writeln!(
            f,
            "{} components of {} materials × {} in {:.1} s wall ({} passes; reading {:.1} s, arithmetic {:.1} s; CPU {}), peak RSS {}, budget {:.2} GB (planned {:.2} GB, panel {} bins)",
            self.components,
            self.materials,
            self.dim,
            self.wall_seconds,
            self.passes,
            self.read_seconds,
            self.compute_seconds,
            secs(self.cpu_seconds),
            self.peak_rss.map_or("?".into(), |r| format!("{:.2} GB", gb(r as f64))),
            gb(self.memory_budget as f64),
            gb(self.planned_bytes as f64),
            self.panel_width
        )?;
        write!(
            f,
            "leading eigenvalues {:?} (first {} hold {:.2} % of the variance found)",
            self.leading_eigenvalues
                .iter()
                .map(|v| format!("{v:.4e}"))
                .collect::<Vec<_>>(),
            self.components,
            100.0 * self.kept_variance
        )
    }
}

/// Reads every chunk of `store` once, without arithmetic: (wall, CPU) seconds.
fn read_once(store: &CorpusStore) -> Result<(f64, Option<f64>)> {
    let (t, c0) = (Instant::now(), brdf::cpu_seconds());
    let (n, dim, w) = (store.len(), store.dim(), store.info().chunk.1);
    // panels of one chunk column: the smallest buffer, every chunk decoded once
    let mut buf = vec![0.0f32; n * w];
    for c in (0..dim).step_by(w) {
        let e = (c + w).min(dim);
        buf.resize(n * (e - c), 0.0);
        store.read_panel(c..e, &mut buf)?;
    }
    let cpu = brdf::cpu_seconds().zip(c0).map(|(b, a)| b - a);
    Ok((t.elapsed().as_secs_f64(), cpu))
}

impl PcaJob {
    /// Runs the out-of-core PCA of this job and writes its model (and the optional basis and
    /// figures).
    pub fn run(&self) -> Result<PcaReport> {
        let store = CorpusStore::open_complete(&self.corpus)?;
        let budget = self.memory_budget.0;
        let randomized = PcaMethod::Randomized {
            oversampling: self.oversampling,
            power_iterations: self.power_iterations,
            seed: self.seed,
        };
        let method = match self.method.as_str() {
            "gram" => PcaMethod::Gram,
            "randomized" => randomized,
            "auto" if store.len() <= 2000 => PcaMethod::Gram,
            "auto" => randomized,
            m => {
                return Err(StoreError::InvalidParameter(format!(
                    "method {m:?}: expected gram, randomized or auto"
                )))
            }
        };
        let read = self.measure_read.then(|| read_once(&store)).transpose()?;
        let (t, cpu0) = (Instant::now(), brdf::cpu_seconds());
        let options = OocOptions {
            components: self.components,
            method,
            memory_budget: budget,
        };
        let (pca, stats) = reduce::fit_out_of_core(&store, &options)?;
        let wall_seconds = t.elapsed().as_secs_f64();
        let cpu_seconds = brdf::cpu_seconds().zip(cpu0).map(|(b, a)| b - a);
        let info = store.info();
        let model = reduce::Model {
            names: info.names.clone(),
            log_floor: info.log_floor,
            mapping: reduce::Mapping::Log,
            pca,
            chart: None,
        };
        model.save(&self.out)?;
        let k = model.pca.components;
        let ev = &model.pca.eigenvalues;
        let total: f64 = ev.iter().sum();
        if let Some(p) = &self.basis_npy {
            let bytes = brdf::npy::to_bytes(&[store.dim(), k], &model.pca.basis);
            brdf::write_atomic(p, &bytes)?;
        }
        let report = PcaReport {
            store: self.corpus.display().to_string(),
            materials: store.len(),
            dim: store.dim(),
            value_type: info.value_type.zarr_name().to_string(),
            bytes_on_disk: store.bytes_on_disk(),
            method: format!("{method:?}"),
            components: k,
            memory_budget: budget,
            planned_bytes: stats.planned_bytes,
            peak_rss: brdf::peak_resident_bytes(),
            wall_seconds,
            cpu_seconds,
            passes: stats.passes,
            read_seconds: stats.read_seconds,
            compute_seconds: stats.compute_seconds,
            panel_width: stats.panel_width,
            read_once_seconds: read.map(|r| r.0),
            read_once_cpu_seconds: read.and_then(|r| r.1),
            eigenvalues: ev.iter().take(k).copied().collect(),
            leading_eigenvalues: ev.iter().take(5).copied().collect(),
            kept_variance: ev.iter().take(k).sum::<f64>() / total.max(f64::MIN_POSITIVE),
        };
        if let Some(p) = &self.stats {
            let json = serde_json::to_string_pretty(&report).map_err(|e| {
                StoreError::InvalidParameter(format!("cannot encode the figures: {e}"))
            })?;
            brdf::write_atomic(p, json.as_bytes())?;
        }
        Ok(report)
    }
}
