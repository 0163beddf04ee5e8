//! A synthetic corpus packed into a Zarr store, then its PCA out of core within a memory budget.
//!
//! `cargo run --release -p corpus-store --example synth_and_pca -- [N] [OUT.zarr]`
//!
//! The base materials are the MERL corpus when the shared data is present
//! (`BRDF_DATA_DIR`), otherwise a few analytic materials; the grid is 15 × 15 × 30.

use corpus_store::pack;
use corpus_store::StoreOptions;
use corpus_store::{SynthOptions, Synthesizer};
use reduce::{fit_out_of_core, OocOptions, PcaMethod};
use sampling::SampleGrid;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let mut args = std::env::args().skip(1);
    let n: usize = args.next().map_or(Ok(200), |s| s.parse())?;
    let dir = tempfile::tempdir()?;
    let out = args
        .next()
        .map_or_else(|| dir.path().join("synth.zarr"), Into::into);
    let merl = brdf::data_dir().join("nbrdf/merl");
    let base = if merl.is_dir() {
        brdf::sources(&[merl])?
    } else {
        brdf::sources(&["lambert:kd=0.4", "ggx:alpha=0.1", "ggx:alpha=0.4,kd=0.2"])?
    };
    let grid = SampleGrid::new(6, 6, 6)?;
    let options = SynthOptions {
        n,
        seed: 1,
        ..SynthOptions::default()
    };
    let synth = Synthesizer::from_sources(&base, grid, options)?;
    println!("material 0 = {}", synth.recipe(0));
    let store = pack(&synth, &out, StoreOptions::default(), &mut |p| {
        if p.done == p.total {
            println!("packed {} materials", p.total);
        }
    })?;
    println!(
        "{}: {} × {} values, {} bytes on disk",
        out.display(),
        store.len(),
        store.dim(),
        store.bytes_on_disk()
    );
    let options = OocOptions {
        components: 10,
        method: PcaMethod::RANDOMIZED,
        memory_budget: 32 << 20,
    };
    let (pca, stats) = fit_out_of_core(&store, &options)?;
    println!(
        "{} components in {} passes (panels of {} bins); leading eigenvalues {:?}",
        pca.components,
        stats.passes,
        stats.panel_width,
        &pca.eigenvalues[..3]
    );
    Ok(())
}
