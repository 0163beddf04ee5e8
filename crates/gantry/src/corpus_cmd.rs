//! `gantry corpus pack|synth|info|pca`: chunked Zarr corpus stores and the out-of-core PCA
//! (docs/corpus-store.md).

use std::path::PathBuf;
use std::time::Instant;

use anyhow::{bail, Context, Result};
use clap::{Args, Subcommand};
use corpus_store::pack::{DecodedSources, MaterialSource, PackProgress};
use corpus_store::synth::{SynthOptions, Synthesizer};
use corpus_store::{CorpusStore, FaultKind, StoreOptions, ValueType};
use reduce::ooc::{OocOptions, PcaMethod};
use sampling::grid::SampleGrid;

/// Subcommands of `gantry corpus`.
#[derive(Subcommand, Debug)]
pub enum CorpusCommand {
    /// Pack materials (NBRDF directories, .binary files, specs, stores) into a Zarr store
    /// (resumable: rerun the same command after an interruption).
    Pack(PackArgs),
    /// Write a synthetic corpus of N physically valid materials made from measured ones.
    Synth(SynthArgs),
    /// Summarise a store: materials, grid, layout, compression, completeness.
    Info(InfoArgs),
    /// PCA of a store out of core, within a memory budget; writes a model file.
    Pca(PcaArgs),
}

/// Layout options shared by `pack` and `synth`.
#[derive(Args, Debug)]
pub struct LayoutArgs {
    /// Output store directory (e.g. corpus.zarr).
    #[arg(long)]
    out: PathBuf,
    /// Grid: `full` (90×90×180), `quarter` (45×45×90), a stride `S`, or strides `A:B:C`.
    #[arg(long, default_value = "full")]
    grid: String,
    /// Element type of the stored log values: f16 or f32.
    #[arg(long, default_value = "f16")]
    dtype: String,
    /// Materials per chunk.
    #[arg(long, default_value_t = 16)]
    materials_per_chunk: usize,
    /// Bins per chunk [default: from the number of materials, so that one column of chunks
    /// of all materials takes at most 256 MiB as f32: 65,536 bins up to 1,024 materials,
    /// 4,096 for 10,000].
    #[arg(long)]
    bins_per_chunk: Option<usize>,
    /// zstd level.
    #[arg(long, default_value_t = 3)]
    zstd_level: i32,
}

/// Arguments of `gantry corpus pack`.
#[derive(Args, Debug)]
pub struct PackArgs {
    /// Inputs: directories, .binary files, material specs or stores.
    #[arg(required = true)]
    inputs: Vec<PathBuf>,
    #[command(flatten)]
    layout: LayoutArgs,
}

/// Arguments of `gantry corpus synth`.
#[derive(Args, Debug)]
pub struct SynthArgs {
    /// Base materials (directories, files, specs), e.g. the MERL weight directory.
    #[arg(long, num_args = 1.., required = true)]
    from: Vec<PathBuf>,
    /// Number of materials.
    #[arg(long)]
    n: usize,
    /// Seed.
    #[arg(long, default_value_t = 0)]
    seed: u64,
    /// Base materials per convex combination.
    #[arg(long, default_value_t = 3)]
    mix: usize,
    /// Probability of an added GGX lobe.
    #[arg(long, default_value_t = 0.5)]
    lobe_probability: f64,
    #[command(flatten)]
    layout: LayoutArgs,
}

/// Arguments of `gantry corpus info`.
#[derive(Args, Debug)]
pub struct InfoArgs {
    /// The store.
    store: PathBuf,
    /// Also list every material name.
    #[arg(long)]
    names: bool,
    /// Only look for missing chunk files instead of reading and checking every chunk.
    #[arg(long)]
    quick: bool,
}

/// Arguments of `gantry corpus pca`.
#[derive(Args, Debug)]
pub struct PcaArgs {
    /// The store.
    #[arg(long)]
    corpus: PathBuf,
    /// Components kept.
    #[arg(long, default_value_t = 45)]
    components: usize,
    /// Peak memory of the computation, e.g. 2G, 512M (panels, matrices, the basis).
    #[arg(long, default_value = "4G")]
    memory_budget: String,
    /// `gram` (exact, O(N²) memory), `randomized`, or `auto` (Gram up to 2,000 materials).
    #[arg(long, default_value = "auto")]
    method: String,
    /// Power iterations of the randomized method.
    #[arg(long, default_value_t = 2)]
    power_iterations: usize,
    /// Oversampling of the randomized method.
    #[arg(long, default_value_t = 10)]
    oversampling: usize,
    /// Seed of the randomized method.
    #[arg(long, default_value_t = 0)]
    seed: u64,
    /// Output model file (the `reduce` model format, without chart).
    #[arg(long)]
    out: PathBuf,
    /// Also write the run's figures (time, memory, passes) as JSON.
    #[arg(long)]
    stats: Option<PathBuf>,
    /// Also write the components as a `.npy` file (D × K float32, for other tools).
    #[arg(long)]
    basis_npy: Option<PathBuf>,
    /// Before the PCA, read the whole store once without arithmetic and report the time (the
    /// limit of a streamed computation, measured in the same run).
    #[arg(long)]
    measure_read: bool,
}

/// Runs a `gantry corpus` subcommand.
pub fn run(cmd: CorpusCommand) -> Result<()> {
    match cmd {
        CorpusCommand::Pack(a) => {
            let grid = parse_grid(&a.layout.grid)?;
            let src = DecodedSources::new(&a.inputs, grid).context("cannot list the inputs")?;
            pack_with_bar(&src, &a.layout)
        }
        CorpusCommand::Synth(a) => {
            let grid = parse_grid(&a.layout.grid)?;
            let sources =
                brdf::corpus::sources(&a.from).context("cannot list the base materials")?;
            let opts = SynthOptions {
                n: a.n,
                seed: a.seed,
                mix: a.mix,
                lobe_probability: a.lobe_probability,
            };
            eprintln!("decoding {} base materials on the grid …", sources.len());
            let synth = Synthesizer::from_sources(&sources, grid, opts)?;
            pack_with_bar(&synth, &a.layout)
        }
        CorpusCommand::Info(a) => info(&a),
        CorpusCommand::Pca(a) => pca(&a),
    }
}

fn parse_grid(s: &str) -> Result<SampleGrid> {
    let steps: Vec<usize> = match s {
        "full" => vec![1, 1, 1],
        "quarter" => vec![2, 2, 2],
        other => other
            .split(':')
            .map(|x| x.trim().parse::<usize>())
            .collect::<std::result::Result<_, _>>()
            .with_context(|| format!("grid {other:?}: expected full, quarter, S or A:B:C"))?,
    };
    let g = match steps[..] {
        [s] => SampleGrid::new(s, s, s),
        [a, b, c] => SampleGrid::new(a, b, c),
        _ => bail!("grid {s:?}: expected full, quarter, S or A:B:C"),
    }?;
    Ok(g)
}

/// `4G`, `512M`, `64k`, or bytes.
fn parse_bytes(s: &str) -> Result<usize> {
    let t = s.trim();
    let (num, mul) = match t.char_indices().last() {
        Some((i, c)) if c.is_ascii_alphabetic() => {
            let m: usize = match c.to_ascii_uppercase() {
                'K' => 1 << 10,
                'M' => 1 << 20,
                'G' => 1 << 30,
                'T' => 1 << 40,
                _ => bail!("size {s:?}: unknown unit {c}"),
            };
            (&t[..i], m)
        }
        _ => (t, 1),
    };
    let v: f64 = num
        .trim()
        .parse()
        .with_context(|| format!("size {s:?}: expected e.g. 4G, 512M"))?;
    Ok((v * mul as f64) as usize)
}

fn layout(a: &LayoutArgs, materials: usize) -> Result<StoreOptions> {
    Ok(StoreOptions {
        value_type: a.dtype.parse::<ValueType>()?,
        materials_per_chunk: a.materials_per_chunk,
        bins_per_chunk: a
            .bins_per_chunk
            .unwrap_or_else(|| corpus_store::store::bins_per_chunk_for(materials)),
        zstd_level: a.zstd_level,
    })
}

fn pack_with_bar(src: &dyn MaterialSource, a: &LayoutArgs) -> Result<()> {
    let options = layout(a, src.len())?;
    let bar = indicatif::ProgressBar::new(src.len() as u64);
    bar.set_style(
        indicatif::ProgressStyle::with_template(
            "{elapsed_precise} [{bar:40}] {pos}/{len} materials ({per_sec}, eta {eta}) {msg}",
        )
        .unwrap_or_else(|_| indicatif::ProgressStyle::default_bar()),
    );
    let t = Instant::now();
    let mut skipped = 0;
    let store = corpus_store::pack::pack(src, &a.out, options, &mut |p: PackProgress| {
        bar.set_position(p.done as u64);
        skipped = p.skipped;
        if p.skipped > 0 {
            bar.set_message(format!("{} already on disk", p.skipped));
        }
    })
    .with_context(|| format!("cannot pack {}", a.out.display()))?;
    bar.finish();
    let info = store.info();
    let disk = store.bytes_on_disk();
    println!(
        "packed {} materials ({} resumed from disk) into {} in {:.1} s: {} × {} {}, {:.2} GB raw, {:.2} GB on disk (ratio {:.2})",
        store.len(),
        skipped,
        a.out.display(),
        t.elapsed().as_secs_f64(),
        store.len(),
        store.dim(),
        info.value_type.zarr_name(),
        info.raw_bytes() as f64 / 1e9,
        disk as f64 / 1e9,
        info.raw_bytes() as f64 / disk.max(1) as f64
    );
    Ok(())
}

fn info(a: &InfoArgs) -> Result<()> {
    let s = CorpusStore::open(&a.store)
        .with_context(|| format!("cannot open {}", a.store.display()))?;
    let i = s.info();
    let (th, td, pd) = i.grid.shape();
    let (cm, cb) = i.chunk_grid();
    let missing = s.missing_chunks();
    let disk = s.bytes_on_disk();
    println!("store        {}", a.store.display());
    println!("materials    {}", i.len());
    println!(
        "grid         {th} × {td} × {pd} × 3 (strides {}:{}:{}), D = {}",
        i.grid.theta_h_step,
        i.grid.theta_d_step,
        i.grid.phi_d_step,
        i.dim()
    );
    println!(
        "values       {} of ln(max(f,0) + {})",
        i.value_type.zarr_name(),
        i.log_floor
    );
    println!(
        "chunks       {} materials × {} bins ({cm} × {cb} chunks), zstd{}",
        i.chunk.0,
        i.chunk.1,
        if s.has_checksums() { " + crc32c" } else { "" }
    );
    println!(
        "size         {:.3} GB raw, {:.3} GB on disk (ratio {:.2})",
        i.raw_bytes() as f64 / 1e9,
        disk as f64 / 1e9,
        i.raw_bytes() as f64 / disk.max(1) as f64
    );
    if a.quick {
        if missing == 0 {
            println!("complete     yes (files present; not verified: --quick)");
        } else {
            println!(
                "complete     no: {missing} of {} chunks missing (resume the pack)",
                cm * cb
            );
        }
    } else {
        let bar = indicatif::ProgressBar::new(cm as u64);
        bar.set_style(
            indicatif::ProgressStyle::with_template(
                "verifying {bar:30} {pos}/{len} material blocks {elapsed}",
            )
            .expect("valid template"),
        );
        let v = s.verify(&|done| bar.set_position(done as u64));
        bar.finish_and_clear();
        let (missing, damaged, unreadable) = (
            v.count(FaultKind::Missing),
            v.count(FaultKind::Damaged),
            v.count(FaultKind::Unreadable),
        );
        let sums = if v.checksummed {
            "crc32c checksums verified"
        } else {
            "no checksums in this store (format 1): decoded only"
        };
        if v.is_intact() {
            println!(
                "complete     yes: all {} chunks read back ({sums})",
                v.chunks
            );
        } else {
            println!(
                "complete     no: {missing} missing, {damaged} damaged, {unreadable} unreadable of {} chunks ({sums})",
                v.chunks
            );
            for f in &v.faults {
                println!(
                    "  chunk {}/{}: {:?}: {}",
                    f.chunk.0, f.chunk.1, f.kind, f.detail
                );
            }
        }
        print_names(i, a.names);
        if !v.is_intact() {
            bail!(
                "{}: {} faulty chunks; run `gantry corpus pack` (or `synth`) again with the same --out to re-pack them",
                a.store.display(),
                v.faults.len()
            );
        }
        return Ok(());
    }
    print_names(i, a.names);
    Ok(())
}

fn print_names(i: &corpus_store::StoreInfo, all: bool) {
    if all {
        for n in &i.names {
            println!("{n}");
        }
    } else {
        let shown: Vec<&str> = i.names.iter().take(5).map(String::as_str).collect();
        println!(
            "names        {}{}",
            shown.join(", "),
            if i.len() > 5 { ", …" } else { "" }
        );
    }
}

fn pca(a: &PcaArgs) -> Result<()> {
    let store = CorpusStore::open_complete(&a.corpus)
        .with_context(|| format!("cannot open {}", a.corpus.display()))?;
    let budget = parse_bytes(&a.memory_budget)?;
    let randomized = PcaMethod::Randomized {
        oversampling: a.oversampling,
        power_iterations: a.power_iterations,
        seed: a.seed,
    };
    let method = match a.method.as_str() {
        "gram" => PcaMethod::Gram,
        "randomized" => randomized,
        "auto" if store.len() <= 2000 => PcaMethod::Gram,
        "auto" => randomized,
        m => bail!("method {m:?}: expected gram, randomized or auto"),
    };
    let mut read_once = None;
    if a.measure_read {
        let (tr, c0) = (Instant::now(), brdf::process::cpu_seconds());
        let (n, dim, w) = (store.len(), store.dim(), store.info().chunk.1);
        // panels of one chunk column: the smallest buffer, every chunk decoded once
        let mut buf = vec![0.0f32; n * w];
        for c in (0..dim).step_by(w) {
            let e = (c + w).min(dim);
            buf.resize(n * (e - c), 0.0);
            store.read_panel(c..e, &mut buf)?;
        }
        let secs = tr.elapsed().as_secs_f64();
        read_once = Some(secs);
        println!(
            "read the store once in {secs:.1} s wall (CPU {}): {:.2} GB on disk, {:.2} GB of values decoded ({:.2} GB/s)",
            brdf::process::cpu_seconds().zip(c0).map_or("?".into(), |(b, a)| format!("{:.1} s", b - a)),
            store.bytes_on_disk() as f64 / 1e9,
            (n * dim * 4) as f64 / 1e9,
            (n * dim * 4) as f64 / 1e9 / secs
        );
        drop(buf);
    }
    let (t, cpu0) = (Instant::now(), brdf::process::cpu_seconds());
    let options = OocOptions {
        components: a.components,
        method,
        memory_budget: budget,
    };
    let (pca, stats) = reduce::ooc::fit(&store, &options)?;
    let wall = t.elapsed().as_secs_f64();
    let cpu = brdf::process::cpu_seconds().zip(cpu0).map(|(b, a)| b - a);
    let model = reduce::model::Model {
        names: store.info().names.clone(),
        log_floor: store.info().log_floor,
        pca,
        chart: None,
    };
    model
        .save(&a.out)
        .with_context(|| format!("cannot write {}", a.out.display()))?;
    let rss = brdf::process::peak_resident_bytes();
    let ev = &model.pca.eigenvalues;
    let total: f64 = ev.iter().sum();
    println!(
        "{} components of {} materials × {} in {:.1} s wall ({} passes; reading {:.1} s, arithmetic {:.1} s; CPU {}), peak RSS {}, budget {:.2} GB (planned {:.2} GB, panel {} bins)",
        model.pca.components,
        store.len(),
        store.dim(),
        wall,
        stats.passes,
        stats.read_seconds,
        stats.compute_seconds,
        cpu.map_or("?".into(), |c| format!("{c:.1} s")),
        rss.map_or("?".into(), |r| format!("{:.2} GB", r as f64 / 1e9)),
        budget as f64 / 1e9,
        stats.planned_bytes as f64 / 1e9,
        stats.panel_width
    );
    println!(
        "leading eigenvalues {:?} (first {} hold {:.2} % of the variance found)",
        ev.iter()
            .take(5)
            .map(|v| format!("{v:.4e}"))
            .collect::<Vec<_>>(),
        model.pca.components,
        100.0 * ev.iter().take(model.pca.components).sum::<f64>() / total.max(f64::MIN_POSITIVE)
    );
    if let Some(p) = &a.basis_npy {
        let bytes = brdf::npy::to_bytes(&[store.dim(), model.pca.components], &model.pca.basis);
        brdf::write_atomic(p, &bytes)?;
    }
    if let Some(p) = &a.stats {
        let j = serde_json::json!({
            "store": a.corpus.display().to_string(),
            "materials": store.len(),
            "dim": store.dim(),
            "value_type": store.info().value_type.zarr_name(),
            "bytes_on_disk": store.bytes_on_disk(),
            "method": format!("{method:?}"),
            "components": model.pca.components,
            "memory_budget": budget,
            "planned_bytes": stats.planned_bytes,
            "peak_rss": rss,
            "wall_seconds": wall,
            "cpu_seconds": cpu,
            "passes": stats.passes,
            "read_seconds": stats.read_seconds,
            "compute_seconds": stats.compute_seconds,
            "panel_width": stats.panel_width,
            "read_once_seconds": read_once,
            "eigenvalues": ev.iter().take(model.pca.components).collect::<Vec<_>>(),
        });
        brdf::write_atomic(p, serde_json::to_string_pretty(&j)?.as_bytes())?;
    }
    Ok(())
}
