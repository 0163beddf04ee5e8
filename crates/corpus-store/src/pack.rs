//! Packing materials into a store: resumable, one material block at a time.

use std::path::Path;

use brdf::Source;
use rayon::prelude::*;
use sampling::SampleGrid;

use crate::error::Result;
use crate::store::{CorpusStore, StoreOptions};

/// Materials that can be packed: named, on one grid, produced one at a time as log-space
/// vectors (`3 × grid.len()` values, channel-major).
pub trait MaterialSource: Sync {
    /// Number of materials.
    fn len(&self) -> usize;
    /// Whether there is no material.
    fn is_empty(&self) -> bool {
        self.len() == 0
    }
    /// Name of material `i`.
    fn name(&self, i: usize) -> String;
    /// The grid of the vectors.
    fn grid(&self) -> SampleGrid;
    /// Material `i` as a log-space vector.
    fn log_values(&self, i: usize) -> Result<Vec<f32>>;
}

/// `brdf::corpus` sources (directories, specs, `.binary` files, stores) decoded on a grid.
#[derive(Debug, Clone)]
pub struct DecodedSources {
    sources: Vec<Source>,
    grid: SampleGrid,
}

impl DecodedSources {
    /// The sources of `inputs` ([`brdf::sources`]) on `grid`.
    pub fn new<P: AsRef<Path>>(inputs: &[P], grid: SampleGrid) -> Result<Self> {
        Ok(DecodedSources {
            sources: brdf::sources(inputs)?,
            grid,
        })
    }

    /// The expanded sources.
    pub fn sources(&self) -> &[Source] {
        &self.sources
    }
}

impl MaterialSource for DecodedSources {
    fn len(&self) -> usize {
        self.sources.len()
    }
    fn name(&self, i: usize) -> String {
        self.sources[i].name()
    }
    fn grid(&self) -> SampleGrid {
        self.grid
    }
    fn log_values(&self, i: usize) -> Result<Vec<f32>> {
        let set =
            sampling::TrainingSet::from_sources(std::slice::from_ref(&self.sources[i]), self.grid)?;
        Ok(set
            .material(0)
            .iter()
            .map(|&v| brdf::to_log(v as f64) as f32)
            .collect())
    }
}

/// Progress of a pack, reported after every material block.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct PackProgress {
    /// Materials in blocks done (written now or found complete).
    pub done: usize,
    /// All materials.
    pub total: usize,
    /// Materials of blocks found complete on disk (skipped by a resumed pack).
    pub skipped: usize,
}

/// Packs `source` into the store at `out` (created, or reopened to resume when it holds the
/// same names and layout). Material blocks whose chunks are all on disk and decode (checksums
/// verified, [`CorpusStore::block_faults`]) are skipped; the others, with missing or damaged
/// chunks, are produced (their materials in parallel) and written chunk by chunk atomically. Returns the
/// open store.
pub fn pack(
    source: &dyn MaterialSource,
    out: impl AsRef<Path>,
    options: StoreOptions,
    progress: &mut dyn FnMut(PackProgress),
) -> Result<CorpusStore> {
    let names: Vec<String> = (0..source.len()).map(|i| source.name(i)).collect();
    let store = CorpusStore::create(out, names, source.grid(), options)?;
    let (blocks, _) = store.info().chunk_grid();
    let total = store.len();
    let (mut done, mut skipped) = (0, 0);
    for b in 0..blocks {
        let rows = store.block_rows(b);
        let faults = store.block_faults(b);
        if faults.is_empty() {
            done += rows.len();
            skipped += rows.len();
            progress(PackProgress {
                done,
                total,
                skipped,
            });
            continue;
        }
        for f in faults
            .iter()
            .filter(|f| f.kind != crate::store::FaultKind::Missing)
        {
            tracing::warn!(block = b, chunk = ?f.chunk, detail = %f.detail, "corpus store: re-packing a damaged chunk");
        }
        let parts: Vec<Vec<f32>> = rows
            .clone()
            .into_par_iter()
            .map(|i| source.log_values(i))
            .collect::<Result<_>>()?;
        let values: Vec<f32> = parts.concat();
        drop(parts);
        store.write_block(b, &values)?;
        done += rows.len();
        progress(PackProgress {
            done,
            total,
            skipped,
        });
    }
    store.finish_pack()?;
    tracing::info!(materials = total, skipped, "corpus store packed");
    Ok(store)
}
