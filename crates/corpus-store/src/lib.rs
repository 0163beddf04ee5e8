//! # corpus-store — BRDF corpora beyond one machine's memory
//!
//! A corpus is stored as one chunked, compressed **Zarr v3** array (written with the `zarrs`
//! crate) so that the files open as they are in zarr-python, xarray or any Zarr v3 reader:
//!
//! ```text
//! corpus.zarr/
//!   zarr.json            group; attributes {"format": "reflectance-corpus", "format_version": 2}
//!   values/zarr.json     array N × D, float16 or float32, chunks (materials × bins),
//!                        zstd then crc32c; dimension_names ["material", "bin"]; attributes: names, grid,
//!                        channels, bin_layout, transform
//!   values/c/<i>/<j>     chunk i (materials) × j (bins)
//! ```
//!
//! Row `i` is material `i` in the log space of thesis §4.1 (`ln(max(f, 0) + ε)`,
//! [`brdf::corpus`]), channel major, on a subsampling of the MERL grid
//! ([`sampling::grid::SampleGrid`]; the full 90 × 90 × 180 grid or e.g. the quarter
//! 45 × 45 × 90 grid of strides 2).
//!
//! * [`store`]: [`CorpusStore`] — create, open, write material blocks (each chunk atomically:
//!   encoded under a staging key, renamed into place), read rows or panels of bins, verify
//!   every chunk's checksum ([`CorpusStore::verify`]). A reader refuses a damaged chunk with
//!   [`StoreError::Damaged`]; a resumed pack re-packs it.
//! * [`pack`] and [`PackJob`]: resumable packing of any [`pack::MaterialSource`] (decoded `brdf::corpus`
//!   inputs, or a synthetic corpus).
//! * [`synth`] and [`SynthJob`]: synthetic, physically checked materials from measured ones.
//! * [`CorpusStore`] implements [`reduce::ooc::ColumnPanels`], so [`reduce::ooc::fit`] runs the
//!   PCA out of core; [`register`] makes `brdf::corpus` (and so every `--corpus` option) read
//!   stores.
//!
//! ```
//! use corpus_store::{pack, store::StoreOptions, synth::{Synthesizer, SynthOptions}};
//! use sampling::grid::SampleGrid;
//!
//! // base materials on a coarse grid, a synthetic corpus of 20 made from them
//! let grid = SampleGrid::new(15, 15, 30).unwrap();
//! let base = ["lambert:kd=0.5", "ggx:alpha=0.1", "ggx:alpha=0.4"];
//! let sources = brdf::corpus::sources(&base).unwrap();
//! let opts = SynthOptions { n: 20, seed: 1, ..SynthOptions::default() };
//! let synth = Synthesizer::from_sources(&sources, grid, opts).unwrap();
//!
//! let dir = tempfile::tempdir().unwrap();
//! let path = dir.path().join("corpus.zarr");
//! let layout = StoreOptions { materials_per_chunk: 8, bins_per_chunk: 256, ..StoreOptions::default() };
//! let store = pack::pack(&synth, &path, layout, &mut |_| {}).unwrap();
//! assert_eq!((store.len(), store.dim()), (20, 3 * grid.len()));
//! // every chunk present, with a matching checksum
//! assert!(store.verify(&|_| {}).is_intact());
//!
//! // PCA streamed from the store
//! use reduce::ooc::{fit, OocOptions, PcaMethod};
//! let o = OocOptions { components: 3, method: PcaMethod::Gram, memory_budget: 64 << 20 };
//! let (pca, stats) = fit(&store, &o).unwrap();
//! assert_eq!(pca.components, 3);
//! assert_eq!(stats.passes, 2);
//! ```

#![warn(missing_docs)]

pub mod error;
mod job;
pub mod pack;
pub mod store;
pub mod synth;

use std::ops::Range;
use std::path::Path;
use std::sync::Arc;

pub use error::{Result, StoreError};
pub use job::{
    ByteSize, InfoJob, InfoReport, LayoutOptions, PackJob, PackReport, PcaJob, PcaReport, SynthJob,
};
pub use store::{
    ChunkFault, CorpusStore, FaultKind, StoreInfo, StoreOptions, ValueType, Verification,
};

impl reduce::ooc::ColumnPanels for CorpusStore {
    fn rows(&self) -> usize {
        self.len()
    }
    fn dim(&self) -> usize {
        CorpusStore::dim(self)
    }
    fn column_block(&self) -> usize {
        self.info().chunk.1
    }
    fn read_overhead(&self, _width: usize) -> usize {
        // each reading thread holds one decoded chunk (element type and f32) and its encoding
        let (m, b) = self.info().chunk;
        rayon::current_num_threads() * m * b * (4 + 2 * self.info().value_type.size())
    }
    fn read_columns(
        &self,
        cols: Range<usize>,
        out: &mut [f32],
    ) -> std::result::Result<(), reduce::ooc::SourceError> {
        self.read_panel(cols, out).map_err(|e| Box::new(e) as _)
    }
}

/// The [`brdf::corpus::StoreReader`] of Zarr corpus stores.
#[derive(Debug, Clone, Copy, Default)]
pub struct ZarrStoreReader;

impl brdf::corpus::StoreReader for ZarrStoreReader {
    fn accepts(&self, path: &Path) -> bool {
        CorpusStore::is_store(path)
    }
    fn names(&self, path: &Path) -> std::result::Result<(Vec<String>, usize), brdf::BrdfError> {
        let s = CorpusStore::open_complete(path).map_err(|e| wrap(path, e))?;
        Ok((s.info().names.clone(), s.dim()))
    }
    fn log_rows(
        &self,
        path: &Path,
        rows: Range<usize>,
    ) -> std::result::Result<Vec<f32>, brdf::BrdfError> {
        let s = CorpusStore::open(path).map_err(|e| wrap(path, e))?;
        s.read_rows(rows).map_err(|e| wrap(path, e))
    }
    fn format(&self) -> &str {
        "zarr-v3 corpus store"
    }
}

fn wrap(path: &Path, e: StoreError) -> brdf::BrdfError {
    brdf::spec::resolver_error(&path.display().to_string(), e)
}

/// Registers [`ZarrStoreReader`] with `brdf::corpus`, so that a store directory is accepted
/// wherever a corpus input is (call once at start-up).
pub fn register() {
    brdf::corpus::register_store_reader(Arc::new(ZarrStoreReader));
}
