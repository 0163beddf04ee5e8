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
//! [`brdf::Corpus`]), channel major, on a subsampling of the MERL grid
//! ([`sampling::SampleGrid`]; the full 90 × 90 × 180 grid or e.g. the quarter
//! 45 × 45 × 90 grid of strides 2).
//!
//! The work flows from materials to a store to a model:
//!
//! 1. **Choose materials.** A [`MaterialSource`] yields log-space rows: [`DecodedSources`]
//!    decodes `brdf` corpus inputs (neural-BRDF directories, `.binary` files, specs), and a
//!    [`Synthesizer`] makes synthetic, physically checked materials from measured ones
//!    ([`validity`] is the check).
//! 2. **Pack.** [`pack`] writes them into a [`CorpusStore`], resumably, one material block at a
//!    time; each chunk is written atomically (encoded under a staging key, renamed into place).
//!    [`StoreOptions`] sets the value type and the chunk shape.
//! 3. **Read and check.** [`CorpusStore`] reads rows or panels of bins and verifies every
//!    chunk's checksum ([`CorpusStore::verify`], a [`Verification`]); a reader refuses a damaged
//!    chunk with [`StoreError::Damaged`], and a resumed pack re-packs it.
//! 4. **Use.** [`CorpusStore`] implements [`reduce::ColumnPanels`], so
//!    [`reduce::fit_out_of_core`] runs the PCA of thesis §4.1 out of core; [`register`] installs
//!    the [`ZarrStoreReader`] so that `brdf`'s corpus loading (and so every `--corpus` option)
//!    reads stores.
//!
//! [`PackJob`], [`SynthJob`], [`InfoJob`] and [`PcaJob`] are the jobs behind
//! `gantry corpus pack|synth|info|pca`: options in, one run function, a serde report out whose
//! `Display` is what the command prints.
//!
//! # Examples
//!
//! ```
//! use corpus_store::{pack, StoreOptions, Synthesizer, SynthOptions};
//! use sampling::SampleGrid;
//!
//! // base materials on a coarse grid, a synthetic corpus of 20 made from them
//! let grid = SampleGrid::new(15, 15, 30).unwrap();
//! let base = ["lambert:kd=0.5", "ggx:alpha=0.1", "ggx:alpha=0.4"];
//! let sources = brdf::sources(&base).unwrap();
//! let opts = SynthOptions { n: 20, seed: 1, ..SynthOptions::default() };
//! let synth = Synthesizer::from_sources(&sources, grid, opts).unwrap();
//!
//! let dir = tempfile::tempdir().unwrap();
//! let path = dir.path().join("corpus.zarr");
//! let layout = StoreOptions { materials_per_chunk: 8, bins_per_chunk: 256, ..StoreOptions::default() };
//! let store = pack(&synth, &path, layout, &mut |_| {}).unwrap();
//! assert_eq!((store.len(), store.dim()), (20, 3 * grid.len()));
//! // every chunk present, with a matching checksum
//! assert!(store.verify(&|_| {}).is_intact());
//!
//! // PCA streamed from the store
//! use reduce::{fit_out_of_core, OocOptions, PcaMethod};
//! let o = OocOptions { components: 3, method: PcaMethod::Gram, memory_budget: 64 << 20 };
//! let (pca, stats) = fit_out_of_core(&store, &o).unwrap();
//! assert_eq!(pca.components, 3);
//! assert_eq!(stats.passes, 2);
//! ```

#![warn(missing_docs)]

mod error;
mod job;
mod pack;
mod store;
mod synth;

pub use pack::{pack, DecodedSources, MaterialSource, PackProgress};
pub use store::bins_per_chunk_for;
pub use synth::{validity, SynthOptions, Synthesizer, Validity, MAX_ALBEDO};

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

impl reduce::ColumnPanels for CorpusStore {
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
    ) -> std::result::Result<(), reduce::SourceError> {
        self.read_panel(cols, out).map_err(|e| Box::new(e) as _)
    }
}

/// The [`brdf::StoreReader`] of Zarr corpus stores.
#[derive(Debug, Clone, Copy, Default)]
pub struct ZarrStoreReader;

impl brdf::StoreReader for ZarrStoreReader {
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
    brdf::resolver_error(&path.display().to_string(), e)
}

/// Registers [`ZarrStoreReader`] with `brdf::corpus`, so that a store directory is accepted
/// wherever a corpus input is (call once at start-up).
pub fn register() {
    brdf::register_store_reader(Arc::new(ZarrStoreReader));
}
