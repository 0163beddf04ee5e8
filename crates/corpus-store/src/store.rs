//! The on-disk corpus store: one Zarr v3 array of materials × bins (see the [crate docs](crate)).

use std::ops::Range;
use std::path::{Path, PathBuf};
use std::sync::Arc;

use half::f16;
use rayon::prelude::*;
use sampling::SampleGrid;
use serde_json::{json, Map, Value};
use zarrs::array::{Array, ArrayBuilder};
use zarrs::filesystem::FilesystemStore;
use zarrs::group::GroupBuilder;

use crate::error::{io, zarr, Result, StoreError};

/// Value of the root group's `format` attribute.
pub const FORMAT: &str = "reflectance-corpus";
/// Version of the layout described in the crate docs. Version 2 adds a `crc32c` checksum to
/// every chunk; stores of version 1 (no checksum) are still read.
pub const FORMAT_VERSION: u64 = 2;
/// Path of the corpus array inside the store.
pub const ARRAY_PATH: &str = "/values";
/// The most values one chunk may hold (1 GiB as `f32`).
pub const MAX_CHUNK_VALUES: usize = 1 << 28;
/// Where chunks are encoded before they are renamed into place (removed when the pack ends).
const STAGING_PATH: &str = "/pack-staging";

/// Element type of the stored log-space values.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ValueType {
    /// IEEE half precision (2 bytes; about 3 significant digits of the log value, i.e. a
    /// relative error of the BRDF value below 0.4 % for log values within ±8).
    F16,
    /// IEEE single precision (4 bytes; what the in-memory corpus holds).
    F32,
}

impl ValueType {
    /// Bytes per value.
    pub fn size(self) -> usize {
        match self {
            ValueType::F16 => 2,
            ValueType::F32 => 4,
        }
    }

    /// The Zarr data-type name (`float16`, `float32`).
    pub fn zarr_name(self) -> &'static str {
        match self {
            ValueType::F16 => "float16",
            ValueType::F32 => "float32",
        }
    }

    fn from_zarr_name(name: &str) -> Option<ValueType> {
        match name {
            "float16" => Some(ValueType::F16),
            "float32" => Some(ValueType::F32),
            _ => None,
        }
    }
}

impl std::str::FromStr for ValueType {
    type Err = StoreError;
    fn from_str(s: &str) -> Result<Self> {
        match s.to_ascii_lowercase().as_str() {
            "f16" | "float16" => Ok(ValueType::F16),
            "f32" | "float32" => Ok(ValueType::F32),
            other => Err(StoreError::InvalidParameter(format!(
                "value type {other:?}: expected f16 or f32"
            ))),
        }
    }
}

/// Layout and compression of a new store.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct StoreOptions {
    /// Element type.
    pub value_type: ValueType,
    /// Materials per chunk (the material block).
    pub materials_per_chunk: usize,
    /// Bins per chunk (the bin block; log-space values of one channel run consecutively).
    pub bins_per_chunk: usize,
    /// zstd compression level (0 = the library default, 1 fastest … 22 smallest).
    pub zstd_level: i32,
}

impl StoreOptions {
    /// The default layout with the bin block sized for a corpus of `n` materials
    /// ([`bins_per_chunk_for`]), so that the out-of-core PCA can stream it in panels within a
    /// few GB whatever `n` is.
    pub fn sized_for(n: usize) -> Self {
        StoreOptions {
            bins_per_chunk: bins_per_chunk_for(n),
            ..StoreOptions::default()
        }
    }
}

/// Bins per chunk for a corpus of `n` materials: the largest power of two up to 65,536 for
/// which one column of chunks (all `n` materials over the chunk's bins, as `f32`) takes at
/// most 256 MiB, and at least 1,024.
///
/// A panel of the out-of-core PCA ([`reduce::fit_out_of_core`]) holds whole columns of chunks, so this
/// bounds the memory the PCA needs per panel: 65,536 bins up to 1,024 materials, 4,096 bins
/// for 10,000 materials.
///
/// ```
/// use corpus_store::bins_per_chunk_for;
/// assert_eq!(bins_per_chunk_for(96), 65_536);
/// assert_eq!(bins_per_chunk_for(10_000), 4_096);
/// assert_eq!(bins_per_chunk_for(10_000_000), 1_024);
/// ```
pub fn bins_per_chunk_for(n: usize) -> usize {
    const COLUMN_BYTES: usize = 256 << 20;
    let mut bins = 65_536;
    while bins > 1_024 && n.saturating_mul(bins).saturating_mul(4) > COLUMN_BYTES {
        bins /= 2;
    }
    bins
}

impl Default for StoreOptions {
    /// `f16`, 16 materials × 65,536 bins per chunk (2 MiB raw), zstd level 3.
    fn default() -> Self {
        StoreOptions {
            value_type: ValueType::F16,
            materials_per_chunk: 16,
            bins_per_chunk: 65_536,
            zstd_level: 3,
        }
    }
}

/// Everything a store records about its corpus besides the values.
#[derive(Debug, Clone, PartialEq)]
pub struct StoreInfo {
    /// Material names, in row order.
    pub names: Vec<String>,
    /// The angular grid of the bins (a subsampling of the MERL grid).
    pub grid: SampleGrid,
    /// Floor `ε` of the log transform `ln(max(f, 0) + ε)` the values are stored in.
    pub log_floor: f64,
    /// Element type.
    pub value_type: ValueType,
    /// Chunk shape (materials, bins).
    pub chunk: (usize, usize),
}

impl StoreInfo {
    /// Number of materials `N`.
    pub fn len(&self) -> usize {
        self.names.len()
    }

    /// Whether the store holds no material.
    pub fn is_empty(&self) -> bool {
        self.names.is_empty()
    }

    /// Length of one material vector: 3 channels × grid points.
    pub fn dim(&self) -> usize {
        3 * self.grid.len()
    }

    /// Number of chunks along (materials, bins).
    pub fn chunk_grid(&self) -> (usize, usize) {
        (
            self.len().div_ceil(self.chunk.0),
            self.dim().div_ceil(self.chunk.1),
        )
    }

    /// Uncompressed size of the values in bytes.
    pub fn raw_bytes(&self) -> u64 {
        (self.len() * self.dim() * self.value_type.size()) as u64
    }
}

/// What is wrong with a chunk ([`CorpusStore::verify`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize)]
pub enum FaultKind {
    /// No chunk file: the pack has not written it (or it was deleted).
    Missing,
    /// The file does not decode: checksum mismatch, truncation, wrong size.
    Damaged,
    /// The file could not be read at all (permissions, I/O).
    Unreadable,
}

/// One faulty chunk.
#[derive(Debug, Clone, PartialEq, Eq, serde::Serialize)]
pub struct ChunkFault {
    /// (material block, bin block).
    pub chunk: (usize, usize),
    /// What is wrong.
    pub kind: FaultKind,
    /// The decoder's or file system's words.
    pub detail: String,
}

/// The outcome of [`CorpusStore::verify`].
#[derive(Debug, Clone, PartialEq, Eq, serde::Serialize)]
pub struct Verification {
    /// Chunks in the store's chunk grid.
    pub chunks: usize,
    /// Whether the chunks carry checksums (without them a flipped bit may decode unnoticed).
    pub checksummed: bool,
    /// The faulty chunks, in index order.
    pub faults: Vec<ChunkFault>,
}

impl Verification {
    /// Whether every chunk is present and decodes.
    pub fn is_intact(&self) -> bool {
        self.faults.is_empty()
    }

    /// Number of faults of `kind`.
    pub fn count(&self, kind: FaultKind) -> usize {
        self.faults.iter().filter(|f| f.kind == kind).count()
    }
}

/// An open corpus store.
///
/// # Examples
///
/// ```
/// use corpus_store::{pack, CorpusStore, DecodedSources, MaterialSource, StoreOptions, ValueType};
/// use sampling::SampleGrid;
///
/// let grid = SampleGrid::new(15, 15, 30).unwrap();
/// let specs = ["lambert:kd=0.5", "ggx:alpha=0.2,kd=0.1", "ggx:alpha=0.05,kd=0.3"];
/// let source = DecodedSources::new(&specs, grid).unwrap();
/// let dir = tempfile::tempdir().unwrap();
/// let path = dir.path().join("corpus.zarr");
/// let layout = StoreOptions {
///     value_type: ValueType::F32,
///     materials_per_chunk: 2,
///     bins_per_chunk: 128,
///     zstd_level: 3,
/// };
/// pack(&source, &path, layout, &mut |_| {}).unwrap();
///
/// let store = CorpusStore::open_complete(&path).unwrap();
/// assert_eq!(store.info().names, specs);
/// assert_eq!((store.len(), store.dim()), (3, 3 * grid.len()));
/// assert_eq!(store.info().chunk_grid(), (2, store.dim().div_ceil(128)));
/// // Rows come back exactly as packed (f32 values), across the two material blocks.
/// let rows = store.read_rows(0..3).unwrap();
/// for i in 0..3 {
///     assert_eq!(rows[i * store.dim()..(i + 1) * store.dim()], source.log_values(i).unwrap());
/// }
/// // A panel holds the same values, bin-major within each material.
/// let mut panel = vec![0.0f32; 3 * 128];
/// store.read_panel(0..128, &mut panel).unwrap();
/// assert_eq!(panel[128..256], rows[store.dim()..store.dim() + 128]);
/// // Stored values are ln(f + floor): the Lambertian row never exceeds kd/π.
/// let lambert = &rows[..store.dim()];
/// let peak = lambert.iter().map(|&y| brdf::from_log(y as f64)).fold(0.0, f64::max);
/// assert!((peak - 0.5 / std::f64::consts::PI).abs() < 1e-6, "{peak}");
/// assert!(store.verify(&|_| {}).is_intact());
/// ```
pub struct CorpusStore {
    path: PathBuf,
    info: StoreInfo,
    array: Array<FilesystemStore>,
    staging: Array<FilesystemStore>,
}

impl std::fmt::Debug for CorpusStore {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("CorpusStore")
            .field("path", &self.path)
            .field("materials", &self.info.len())
            .field("dim", &self.info.dim())
            .finish()
    }
}

fn grid_json(grid: &SampleGrid) -> Value {
    let (a, b, c) = grid.shape();
    json!({
        "shape": [a, b, c],
        "steps": [grid.theta_h_step, grid.theta_d_step, grid.phi_d_step],
        "axes": ["theta_half", "theta_diff", "phi_diff"],
    })
}

impl CorpusStore {
    /// Whether `path` looks like a corpus store (a directory with a Zarr `zarr.json` and the
    /// corpus array); it does not validate the attributes.
    pub fn is_store(path: impl AsRef<Path>) -> bool {
        let p = path.as_ref();
        p.join("zarr.json").is_file() && p.join("values").join("zarr.json").is_file()
    }

    /// Creates a store for `names` on `grid`, or reopens it when it already exists with exactly
    /// the same names, grid and layout (resuming a pack). An existing store that differs is a
    /// [`StoreError::Format`] error.
    pub fn create(
        path: impl AsRef<Path>,
        names: Vec<String>,
        grid: SampleGrid,
        options: StoreOptions,
    ) -> Result<CorpusStore> {
        let path = path.as_ref();
        if names.is_empty() {
            return Err(StoreError::InvalidParameter(
                "a store needs materials".into(),
            ));
        }
        if options.materials_per_chunk == 0 || options.bins_per_chunk == 0 {
            return Err(StoreError::InvalidParameter(
                "chunk sizes must be positive".into(),
            ));
        }
        if options
            .materials_per_chunk
            .saturating_mul(options.bins_per_chunk)
            > MAX_CHUNK_VALUES
        {
            return Err(StoreError::InvalidParameter(format!(
                "chunks of {} × {} values are larger than {MAX_CHUNK_VALUES}",
                options.materials_per_chunk, options.bins_per_chunk
            )));
        }
        if Self::is_store(path) {
            let existing = Self::open(path)?;
            let i = &existing.info;
            let want = StoreInfo {
                names,
                grid,
                log_floor: brdf::LOG_FLOOR,
                value_type: options.value_type,
                chunk: (options.materials_per_chunk, options.bins_per_chunk),
            };
            if *i != want {
                return Err(StoreError::Format {
                    path: path.display().to_string(),
                    reason: "a store with other materials, grid or layout exists here (remove it or choose another --out)".into(),
                });
            }
            return Ok(existing);
        }
        std::fs::create_dir_all(path).map_err(io(path))?;
        let fs = Arc::new(FilesystemStore::new(path).map_err(zarr("opening the directory"))?);
        let mut root = Map::new();
        root.insert("format".into(), json!(FORMAT));
        root.insert("format_version".into(), json!(FORMAT_VERSION));
        GroupBuilder::new()
            .attributes(root)
            .build(fs.clone(), "/")
            .map_err(zarr("root group"))?
            .store_metadata()
            .map_err(zarr("root group metadata"))?;
        let (n, dim) = (names.len(), 3 * grid.len());
        let mut attrs = Map::new();
        attrs.insert("names".into(), json!(names));
        attrs.insert("grid".into(), grid_json(&grid));
        attrs.insert("channels".into(), json!(["R", "G", "B"]));
        attrs.insert(
            "bin_layout".into(),
            json!("channel-major: bin = channel * P + (i_theta_half * n_theta_diff + i_theta_diff) * n_phi_diff + i_phi_diff, P = grid points"),
        );
        attrs.insert(
            "transform".into(),
            json!({"kind": "log", "formula": "ln(max(f, 0) + floor)", "floor": brdf::LOG_FLOOR, "units_of_f": "1/sr"}),
        );
        let (dtype, fill): (_, zarrs::array::FillValue) = match options.value_type {
            ValueType::F16 => (zarrs::array::data_type::float16(), f16::NAN.into()),
            ValueType::F32 => (zarrs::array::data_type::float32(), f32::NAN.into()),
        };
        let mut builder = ArrayBuilder::new(
            vec![n as u64, dim as u64],
            vec![
                options.materials_per_chunk as u64,
                options.bins_per_chunk as u64,
            ],
            dtype,
            fill,
        );
        builder
            .bytes_to_bytes_codecs(vec![
                Arc::new(zarrs::array::codec::ZstdCodec::new(
                    options.zstd_level,
                    false,
                )),
                // checked by every reader (zarrs and zarr-python alike) before decompression
                Arc::new(zarrs::array::codec::Crc32cCodec::new()),
            ])
            .dimension_names(Some(["material", "bin"]))
            .attributes(attrs);
        let array = builder
            .build(fs.clone(), ARRAY_PATH)
            .map_err(zarr("corpus array"))?;
        array
            .store_metadata()
            .map_err(zarr("corpus array metadata"))?;
        drop(array);
        Self::open(path)
    }

    /// Opens an existing store (complete or not; see [`Self::missing_chunks`]).
    pub fn open(path: impl AsRef<Path>) -> Result<CorpusStore> {
        let path = path.as_ref();
        let bad = |reason: &str| StoreError::Format {
            path: path.display().to_string(),
            reason: reason.into(),
        };
        if !Self::is_store(path) {
            return Err(bad("no zarr.json with a `values` array"));
        }
        let fs = Arc::new(FilesystemStore::new(path).map_err(zarr("opening the directory"))?);
        let group = zarrs::group::Group::open(fs.clone(), "/").map_err(zarr("root group"))?;
        if group.attributes().get("format").and_then(Value::as_str) != Some(FORMAT) {
            return Err(bad(
                "the root group has no `format: reflectance-corpus` attribute",
            ));
        }
        let array = Array::open(fs.clone(), ARRAY_PATH).map_err(zarr("corpus array"))?;
        let attrs = array.attributes();
        let names: Vec<String> = attrs
            .get("names")
            .and_then(Value::as_array)
            .ok_or_else(|| bad("no `names` attribute"))?
            .iter()
            .map(|v| v.as_str().map(str::to_owned))
            .collect::<Option<_>>()
            .ok_or_else(|| bad("`names` are not strings"))?;
        let steps: Vec<usize> = attrs
            .get("grid")
            .and_then(|g| g.get("steps"))
            .and_then(Value::as_array)
            .map(|a| {
                a.iter()
                    .filter_map(|v| v.as_u64().map(|x| x as usize))
                    .collect()
            })
            .unwrap_or_default();
        if steps.len() != 3 {
            return Err(bad("no `grid.steps` attribute of three strides"));
        }
        let grid = SampleGrid::new(steps[0], steps[1], steps[2])?;
        let log_floor = attrs
            .get("transform")
            .and_then(|t| t.get("floor"))
            .and_then(Value::as_f64)
            .ok_or_else(|| bad("no `transform.floor` attribute"))?;
        let shape = array.shape().to_vec();
        if shape != [names.len() as u64, 3 * grid.len() as u64] {
            return Err(bad("the array shape does not match names × grid"));
        }
        let type_name = array.data_type().name_v3().map(|n| n.to_string());
        let value_type = type_name
            .as_deref()
            .and_then(ValueType::from_zarr_name)
            .ok_or_else(|| bad("the values are neither float16 nor float32"))?;
        let chunk = array.chunk_shape(&[0, 0]).map_err(zarr("chunk shape"))?;
        let chunk = (chunk[0].get() as usize, chunk[1].get() as usize);
        // A reader holds decoded chunks in memory: refuse a header whose chunks no corpus
        // needs (more than 2^28 values, 1 GiB as f32) before any is read.
        if chunk.0.saturating_mul(chunk.1) > MAX_CHUNK_VALUES {
            return Err(bad(&format!(
                "chunks of {} × {} values are larger than {MAX_CHUNK_VALUES}",
                chunk.0, chunk.1
            )));
        }
        let staging = Array::new_with_metadata(fs, STAGING_PATH, array.metadata().clone())
            .map_err(zarr("staging array"))?;
        Ok(CorpusStore {
            path: path.to_path_buf(),
            info: StoreInfo {
                names,
                grid,
                log_floor,
                value_type,
                chunk,
            },
            array,
            staging,
        })
    }

    /// Opens a store and checks that every chunk was written.
    pub fn open_complete(path: impl AsRef<Path>) -> Result<CorpusStore> {
        let s = Self::open(path)?;
        let missing = s.missing_chunks();
        if missing > 0 {
            let (a, b) = s.info.chunk_grid();
            return Err(StoreError::Incomplete {
                path: s.path.display().to_string(),
                missing,
                total: a * b,
            });
        }
        Ok(s)
    }

    /// The store directory.
    pub fn path(&self) -> &Path {
        &self.path
    }

    /// Names, grid, element type and layout.
    pub fn info(&self) -> &StoreInfo {
        &self.info
    }

    /// Number of materials `N`.
    pub fn len(&self) -> usize {
        self.info.len()
    }

    /// Whether the store holds no material (never, for a created store).
    pub fn is_empty(&self) -> bool {
        self.info.is_empty()
    }

    /// Length `D` of one material vector.
    pub fn dim(&self) -> usize {
        self.info.dim()
    }

    /// Rows of material block `block`.
    pub fn block_rows(&self, block: usize) -> Range<usize> {
        let m = self.info.chunk.0;
        block * m..((block + 1) * m).min(self.len())
    }

    fn chunk_file(&self, array: &Array<FilesystemStore>, idx: [u64; 2]) -> PathBuf {
        self.path.join(array.chunk_key(&idx).as_str())
    }

    /// Number of chunks not yet written (files absent; see [`Self::verify`] for damaged ones).
    pub fn missing_chunks(&self) -> usize {
        let (na, nb) = self.info.chunk_grid();
        (0..na)
            .flat_map(|a| (0..nb).map(move |b| (a, b)))
            .filter(|&(a, b)| !self.chunk_file(&self.array, [a as u64, b as u64]).is_file())
            .count()
    }

    /// Whether the store records a checksum for every chunk (format version 2).
    pub fn has_checksums(&self) -> bool {
        std::fs::read(self.path.join("values").join("zarr.json"))
            .ok()
            .and_then(|b| serde_json::from_slice::<Value>(&b).ok())
            .and_then(|m| m.get("codecs").and_then(Value::as_array).cloned())
            .is_some_and(|codecs| {
                codecs
                    .iter()
                    .any(|c| c.get("name").and_then(Value::as_str) == Some("crc32c"))
            })
    }

    /// The faults of chunk `(block, bin_block)`: `None` when it is on disk and decodes (its
    /// checksum matches, it decompresses to the right number of values).
    pub fn check_chunk(&self, block: usize, bin_block: usize) -> Option<ChunkFault> {
        match self.chunk_f32([block as u64, bin_block as u64]) {
            Ok(_) => None,
            Err(StoreError::Incomplete { .. }) => Some(ChunkFault {
                chunk: (block, bin_block),
                kind: FaultKind::Missing,
                detail: "no chunk file".into(),
            }),
            Err(StoreError::Damaged { reason, .. }) => Some(ChunkFault {
                chunk: (block, bin_block),
                kind: FaultKind::Damaged,
                detail: reason,
            }),
            Err(e) => Some(ChunkFault {
                chunk: (block, bin_block),
                kind: FaultKind::Unreadable,
                detail: e.to_string(),
            }),
        }
    }

    /// The faults of the chunks of material block `block` (empty when the block is intact).
    pub fn block_faults(&self, block: usize) -> Vec<ChunkFault> {
        let (_, nb) = self.info.chunk_grid();
        (0..nb)
            .into_par_iter()
            .filter_map(|b| self.check_chunk(block, b))
            .collect()
    }

    /// Reads and decodes every chunk (in parallel), checking its checksum where the store has
    /// them: the missing, damaged and unreadable chunks, in index order. `progress` is called
    /// with the number of material blocks checked so far.
    pub fn verify(&self, progress: &(dyn Fn(usize) + Sync)) -> Verification {
        let (na, nb) = self.info.chunk_grid();
        let done = std::sync::atomic::AtomicUsize::new(0);
        let mut faults: Vec<ChunkFault> = (0..na)
            .into_par_iter()
            .flat_map_iter(|a| {
                let f = self.block_faults(a);
                progress(done.fetch_add(1, std::sync::atomic::Ordering::Relaxed) + 1);
                f
            })
            .collect();
        faults.sort_by_key(|f| f.chunk);
        if !faults.is_empty() {
            tracing::warn!(faults = faults.len(), path = %self.path.display(), "corpus store: faulty chunks");
        }
        Verification {
            chunks: na * nb,
            checksummed: self.has_checksums(),
            faults,
        }
    }

    /// Bytes of all chunk files on disk (the compressed size).
    pub fn bytes_on_disk(&self) -> u64 {
        fn walk(p: &Path) -> u64 {
            let Ok(rd) = std::fs::read_dir(p) else {
                return 0;
            };
            rd.filter_map(|e| e.ok())
                .map(|e| {
                    let p = e.path();
                    if p.is_dir() {
                        walk(&p)
                    } else {
                        e.metadata().map_or(0, |m| m.len())
                    }
                })
                .sum()
        }
        walk(&self.path.join("values").join("c"))
    }

    /// Writes material block `block` (rows [`Self::block_rows`]) given as row-major log-space
    /// `f32` values. Every chunk is encoded under a staging key and renamed into place, so a
    /// chunk file is either complete or absent (the pack resumes from the absent ones).
    pub fn write_block(&self, block: usize, rows: &[f32]) -> Result<()> {
        let r = self.block_rows(block);
        let (dim, (mc, bc)) = (self.dim(), self.info.chunk);
        if r.is_empty() || rows.len() != r.len() * dim {
            return Err(StoreError::InvalidParameter(format!(
                "block {block}: expected {} values, got {}",
                r.len() * dim,
                rows.len()
            )));
        }
        if let Some(i) = rows.iter().position(|v| !v.is_finite()) {
            return Err(StoreError::InvalidParameter(format!(
                "block {block}: value {i} is not finite"
            )));
        }
        let (_, nb) = self.info.chunk_grid();
        (0..nb).into_par_iter().try_for_each(|b| -> Result<()> {
            let c0 = b * bc;
            let len = bc.min(dim - c0);
            let mut chunk = vec![f32::NAN; mc * bc];
            for i in 0..r.len() {
                chunk[i * bc..i * bc + len]
                    .copy_from_slice(&rows[i * dim + c0..i * dim + c0 + len]);
            }
            let idx = [block as u64, b as u64];
            let what = || format!("chunk {block}/{b}");
            match self.info.value_type {
                ValueType::F32 => self.staging.store_chunk(&idx, chunk),
                ValueType::F16 => self.staging.store_chunk(
                    &idx,
                    chunk
                        .iter()
                        .map(|&v| f16::from_f32(v))
                        .collect::<Vec<f16>>(),
                ),
            }
            .map_err(zarr(what()))?;
            let from = self.chunk_file(&self.staging, idx);
            let to = self.chunk_file(&self.array, idx);
            if let Some(parent) = to.parent() {
                std::fs::create_dir_all(parent).map_err(io(parent))?;
            }
            std::fs::rename(&from, &to).map_err(io(&to))?;
            Ok(())
        })?;
        tracing::debug!(block, "corpus store: block written");
        Ok(())
    }

    /// Removes the (then empty) staging directory of a finished pack.
    pub fn finish_pack(&self) -> Result<()> {
        let dir = self.path.join(STAGING_PATH.trim_start_matches('/'));
        match std::fs::remove_dir_all(&dir) {
            Ok(()) => Ok(()),
            Err(e) if e.kind() == std::io::ErrorKind::NotFound => Ok(()),
            Err(e) => Err(io(&dir)(e)),
        }
    }

    /// Decodes chunk `idx` as `f32`: [`StoreError::Incomplete`] when its file is absent,
    /// [`StoreError::Damaged`] when it does not decode.
    fn chunk_f32(&self, idx: [u64; 2]) -> Result<Vec<f32>> {
        use zarrs::array::ArrayError;
        let damaged = |e: ArrayError| match e {
            ArrayError::StorageError(e) => StoreError::Zarr {
                context: format!("reading chunk {}/{}", idx[0], idx[1]),
                source: Box::new(e),
            },
            e => StoreError::Damaged {
                path: self.path.display().to_string(),
                chunk: (idx[0] as usize, idx[1] as usize),
                reason: e.to_string(),
            },
        };
        let v = match self.info.value_type {
            ValueType::F32 => self
                .array
                .retrieve_chunk_if_exists::<Vec<f32>>(&idx)
                .map_err(damaged)?,
            ValueType::F16 => self
                .array
                .retrieve_chunk_if_exists::<Vec<f16>>(&idx)
                .map_err(damaged)?
                .map(|v| v.into_iter().map(f32::from).collect()),
        };
        v.ok_or_else(|| StoreError::Incomplete {
            path: self.path.display().to_string(),
            missing: 1,
            total: {
                let (a, b) = self.info.chunk_grid();
                a * b
            },
        })
    }

    /// Reads materials `rows` (row-major log-space `f32`, `rows.len() × D`).
    pub fn read_rows(&self, rows: Range<usize>) -> Result<Vec<f32>> {
        if rows.start > rows.end || rows.end > self.len() {
            return Err(StoreError::InvalidParameter(format!(
                "rows {rows:?} of a store of {} materials",
                self.len()
            )));
        }
        let (dim, (mc, bc)) = (self.dim(), self.info.chunk);
        let mut out = vec![0.0f32; rows.len() * dim];
        let (_, nb) = self.info.chunk_grid();
        let blocks = rows.start / mc..rows.end.div_ceil(mc);
        for a in blocks {
            let br = self.block_rows(a);
            let lo = br.start.max(rows.start);
            let hi = br.end.min(rows.end);
            let parts: Vec<Vec<f32>> = (0..nb)
                .into_par_iter()
                .map(|b| self.chunk_f32([a as u64, b as u64]))
                .collect::<Result<_>>()?;
            for (b, chunk) in parts.iter().enumerate() {
                let c0 = b * bc;
                let len = bc.min(dim - c0);
                for r in lo..hi {
                    let src = &chunk[(r - br.start) * bc..(r - br.start) * bc + len];
                    let o = (r - rows.start) * dim + c0;
                    out[o..o + len].copy_from_slice(src);
                }
            }
        }
        Ok(out)
    }

    /// Reads the bins `cols` of every material into `out` (row-major `N × cols.len()`).
    /// `cols.start` must be a multiple of the chunk's bin count, and `cols.end` one too or `D`.
    pub fn read_panel(&self, cols: Range<usize>, out: &mut [f32]) -> Result<()> {
        let (n, dim, (mc, bc)) = (self.len(), self.dim(), self.info.chunk);
        let w = cols.len();
        if !cols.start.is_multiple_of(bc)
            || (!cols.end.is_multiple_of(bc) && cols.end != dim)
            || cols.end > dim
        {
            return Err(StoreError::InvalidParameter(format!(
                "bins {cols:?} are not aligned to chunks of {bc} bins (D = {dim})"
            )));
        }
        if out.len() != n * w {
            return Err(StoreError::InvalidParameter(format!(
                "panel buffer of {} values for {n} × {w}",
                out.len()
            )));
        }
        let b0 = cols.start / bc;
        let nbp = w.div_ceil(bc);
        out.par_chunks_mut(mc * w)
            .enumerate()
            .try_for_each(|(a, dst)| -> Result<()> {
                let rows = dst.len() / w;
                for b in b0..b0 + nbp {
                    let chunk = self.chunk_f32([a as u64, b as u64])?;
                    let c0 = b * bc - cols.start;
                    let len = bc.min(w - c0);
                    for r in 0..rows {
                        dst[r * w + c0..r * w + c0 + len]
                            .copy_from_slice(&chunk[r * bc..r * bc + len]);
                    }
                }
                Ok(())
            })
    }
}
