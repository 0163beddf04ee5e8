//! Common Wavelet Basis of the shared MERL materials, its Common Wavelet Coefficient Tree, and
//! the "CWB alone" error of the held-out Nielsen materials (thesis §6.2 and §6.6).
//!
//! ```text
//! cargo run --release -p wavelet --example cwb_merl -- [options]
//!   --mode linear|log|log-centred   function represented per colour channel (default linear):
//!                                   linear = BRDF in 1/sr (the thesis), log = ln(max(f, 0) + floor) (the `reduce` crate's log space),
//!                                   log-centred = log minus the corpus mean log (per channel;
//!                                   the mean itself is added as one more component)
//!   --floor F        log floor in 1/sr (default 1e-3)
//!   --target E       relative L2 error per component (default 0.03)
//!   --wavelet W      haar | cdf53 | db4 (default haar; the tree needs haar)
//!   --limit N        use only the first N MERL materials
//!   --tree-materials K   channels of the first K materials go into the tree (default 45,
//!                        i.e. 135 functions like 45 RGB PCA components)
//!   --evals N        timed tree evaluations (default 1000000)
//!   --out PATH       write the basis (CommonBasis::write format)
//! ```
//! Data: `$BRDF_DATA_DIR/nbrdf/{merl,nielsen}` (default `../shared/data`).

use std::time::Instant;

use brdf::nbrdf::Nbrdf;
use brdf::BINS;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rayon::prelude::*;
use wavelet::relative_l2_error;
use wavelet::{CoefficientTree, CommonBasisBuilder, Layout, Wavelet};

#[derive(Clone, Copy, PartialEq)]
enum Mode {
    Linear,
    Log,
    LogCentred,
}

struct Args {
    mode: Mode,
    floor: f32,
    target: f64,
    wavelet: Wavelet,
    limit: Option<usize>,
    tree_materials: usize,
    evals: usize,
    out: Option<String>,
}

fn parse_args() -> Result<Args, String> {
    let mut a = Args {
        mode: Mode::Linear,
        floor: 1e-3,
        target: 0.03,
        wavelet: Wavelet::Haar,
        limit: None,
        tree_materials: 45,
        evals: 1_000_000,
        out: None,
    };
    let argv: Vec<String> = std::env::args().skip(1).collect();
    let mut i = 0;
    while i < argv.len() {
        let flag = argv[i].as_str();
        let val = argv
            .get(i + 1)
            .ok_or_else(|| format!("{flag} needs a value"))?;
        let num = |v: &str| v.parse::<f64>().map_err(|e| format!("{flag}: {e}"));
        match flag {
            "--mode" => {
                a.mode = match val.as_str() {
                    "linear" => Mode::Linear,
                    "log" => Mode::Log,
                    "log-centred" | "log-centered" => Mode::LogCentred,
                    o => return Err(format!("unknown mode {o}")),
                }
            }
            "--floor" => a.floor = num(val)? as f32,
            "--target" => a.target = num(val)?,
            "--wavelet" => a.wavelet = val.parse()?,
            "--limit" => a.limit = Some(num(val)? as usize),
            "--tree-materials" => a.tree_materials = num(val)? as usize,
            "--evals" => a.evals = num(val)? as usize,
            "--out" => a.out = Some(val.clone()),
            o => return Err(format!("unknown option {o}")),
        }
        i += 2;
    }
    Ok(a)
}

/// Log space of the `reduce` crate: ln(max(f, 0) + floor).
fn log_floor(v: &[f32], floor: f32) -> Vec<f32> {
    v.iter().map(|&x| (x.max(0.0) + floor).ln()).collect()
}

/// The three represented channels of a material table (3 × BINS, channel-major, 1/sr).
fn channels(table: &[f32], args: &Args, mean: Option<&[Vec<f32>]>) -> Vec<Vec<f32>> {
    (0..3)
        .map(|c| {
            let ch = &table[c * BINS..(c + 1) * BINS];
            match args.mode {
                Mode::Linear => ch.to_vec(),
                Mode::Log => log_floor(ch, args.floor),
                Mode::LogCentred => {
                    let m = &mean.expect("mean")[c];
                    log_floor(ch, args.floor)
                        .iter()
                        .zip(m)
                        .map(|(a, b)| a - b)
                        .collect()
                }
            }
        })
        .collect()
}

/// Relative RMS difference in log space: ‖ln(a⁺+ε) − ln(b⁺+ε)‖ / ‖ln(a⁺+ε)‖.
fn log_rel_rms(reference: &[f32], approx: &[f32], floor: f32) -> f64 {
    relative_l2_error(&log_floor(reference, floor), &log_floor(approx, floor))
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args = parse_args()?;
    let data = brdf::data_dir();
    let merl_dir = data.join("nbrdf/merl");
    let mut names = brdf::nbrdf::list(&merl_dir)?;
    if let Some(n) = args.limit {
        names.truncate(n);
    }
    let layout = Layout {
        wavelet: args.wavelet,
        ..Layout::MERL_HAAR
    };
    let mode_name = match args.mode {
        Mode::Linear => "linear".to_string(),
        Mode::Log => format!("log (floor {})", args.floor),
        Mode::LogCentred => format!("log-centred (floor {})", args.floor),
    };
    println!(
        "CWB over {} MERL materials, mode {mode_name}, wavelet {}, target {:.1}% per component",
        names.len(),
        args.wavelet.name(),
        100.0 * args.target
    );
    let t_all = Instant::now();
    let load = |name: &str| -> Result<Vec<f32>, brdf::BrdfError> {
        Ok(Nbrdf::load(&merl_dir, name)?.tabulate_f32())
    };

    // Corpus mean of the log channels (log-centred mode only).
    let mean = if args.mode == Mode::LogCentred {
        let mut acc = vec![vec![0.0f64; BINS]; 3];
        for name in &names {
            let t = load(name)?;
            for (c, a) in acc.iter_mut().enumerate() {
                for (s, &v) in a.iter_mut().zip(&t[c * BINS..(c + 1) * BINS]) {
                    *s += (v.max(0.0) + args.floor).ln() as f64;
                }
            }
        }
        Some(
            acc.into_iter()
                .map(|a| a.iter().map(|s| (s / names.len() as f64) as f32).collect())
                .collect::<Vec<Vec<f32>>>(),
        )
    } else {
        None
    };

    let mut builder = CommonBasisBuilder::new(layout, args.target)?;
    if let Some(m) = &mean {
        let refs: Vec<&[f32]> = m.iter().map(|v| v.as_slice()).collect();
        builder.add_many(&refs)?;
    }
    let mut t_tab = 0.0;
    let mut t_cwb = 0.0;
    let mut tree_functions: Vec<Vec<f32>> = Vec::new();
    for (k, name) in names.iter().enumerate() {
        let t = Instant::now();
        let table = load(name)?;
        t_tab += t.elapsed().as_secs_f64();
        let chans = channels(&table, &args, mean.as_deref());
        let t = Instant::now();
        let refs: Vec<&[f32]> = chans.iter().map(|v| v.as_slice()).collect();
        let stats = builder.add_many(&refs)?;
        t_cwb += t.elapsed().as_secs_f64();
        tracing::info!(name, kept = ?stats.iter().map(|s| s.kept).collect::<Vec<_>>());
        if k < args.tree_materials {
            tree_functions.extend(chans);
        }
    }
    let stats = builder.stats().to_vec();
    let cwb = builder.finish();
    let mut kept: Vec<usize> = stats.iter().map(|s| s.kept).collect();
    kept.sort_unstable();
    let max_err = stats.iter().map(|s| s.relative_error).fold(0.0, f64::max);
    println!(
        "components {}, kept per component: min {} median {} max {} (max predicted error {:.4})",
        stats.len(),
        kept[0],
        kept[kept.len() / 2],
        kept[kept.len() - 1],
        max_err
    );
    println!(
        "CWB size {} = {:.2}% of {} table values (seed: ~69,000 = 4.7%)",
        cwb.len(),
        100.0 * cwb.fraction_of_table(),
        BINS
    );
    println!("CWB per level (0 = coarsest): {:?}", cwb.level_histogram());
    println!(
        "time: tabulation {:.1} s, transforms + thresholding {:.1} s",
        t_tab, t_cwb
    );
    if let Some(p) = &args.out {
        cwb.write(p)?;
        println!("basis written to {p}");
    }

    // Held-out materials represented by the CWB alone (thesis §6.6: 0.7-2.1%).
    let nielsen_dir = data.join("nbrdf/nielsen");
    if let Ok(test_names) = brdf::nbrdf::list(&nielsen_dir) {
        println!("held-out Nielsen materials, CWB alone (relative L2 in the mode's space per channel R G B; log-space relative RMS):");
        for name in &test_names {
            let table = Nbrdf::load(&nielsen_dir, name)?.tabulate_f32();
            let chans = channels(&table, &args, mean.as_deref());
            let proj: Vec<Vec<f32>> = chans
                .par_iter()
                .map(|c| cwb.project(c))
                .collect::<Result<_, _>>()?;
            let errs: Vec<f64> = chans
                .iter()
                .zip(&proj)
                .map(|(a, b)| relative_l2_error(a, b))
                .collect();
            // Back to linear values for the log-space metric.
            let mut log_err = 0.0;
            for c in 0..3 {
                let lin_ref = &table[c * BINS..(c + 1) * BINS];
                let lin_hat: Vec<f32> = match args.mode {
                    Mode::Linear => proj[c].clone(),
                    Mode::Log => proj[c].iter().map(|v| v.exp() - args.floor).collect(),
                    Mode::LogCentred => proj[c]
                        .iter()
                        .zip(&mean.as_ref().expect("mean")[c])
                        .map(|(v, m)| (v + m).exp() - args.floor)
                        .collect(),
                };
                log_err += log_rel_rms(lin_ref, &lin_hat, args.floor) / 3.0;
            }
            println!(
                "  {name:<28} {:6.2}% {:6.2}% {:6.2}%   log {:6.2}%",
                100.0 * errs[0],
                100.0 * errs[1],
                100.0 * errs[2],
                100.0 * log_err
            );
        }
    }

    if args.wavelet != Wavelet::Haar || tree_functions.is_empty() {
        println!("total {:.1} s", t_all.elapsed().as_secs_f64());
        return Ok(());
    }
    // The Common Wavelet Coefficient Tree of the first materials' channels.
    let t = Instant::now();
    let refs: Vec<&[f32]> = tree_functions.iter().map(|v| v.as_slice()).collect();
    let tree = CoefficientTree::from_functions(&cwb, &refs)?;
    let t_build = t.elapsed().as_secs_f64();
    let st = tree.storage();
    println!(
        "tree: {} functions, {} nodes, {} coefficient rows; nodes {:.2} MB + coefficients {:.2} MB = {:.2} MB (dense f32 tables: {:.1} MB, ratio {:.1}x); built in {:.1} s",
        st.functions,
        st.nodes,
        st.rows,
        st.node_bytes as f64 / 1e6,
        st.coefficient_bytes as f64 / 1e6,
        st.total_bytes() as f64 / 1e6,
        st.dense_bytes as f64 / 1e6,
        st.dense_bytes as f64 / st.total_bytes() as f64,
        t_build
    );
    // Check against the inverse transform for one function at random cells.
    let recon = cwb.reconstruct(&cwb.coefficients(refs[0])?)?;
    let mut rng = ChaCha8Rng::seed_from_u64(3);
    let cells: Vec<[usize; 3]> = (0..args.evals.max(1))
        .map(|_| {
            [
                rng.gen_range(0..90),
                rng.gen_range(0..90),
                rng.gen_range(0..180),
            ]
        })
        .collect();
    let mut out = vec![0.0f32; tree.functions()];
    let mut worst = 0.0f32;
    for c in cells.iter().take(10_000) {
        tree.eval_cell(*c, &mut out)?;
        let b = c[2] + 180 * (c[1] + 90 * c[0]);
        worst = worst.max((out[0] - recon[b]).abs() / (1.0 + recon[b].abs()));
    }
    let t = Instant::now();
    let mut visited = 0usize;
    let mut sink = 0.0f32;
    for c in &cells {
        visited += tree.eval_cell(*c, &mut out)?;
        sink += out[0];
    }
    let dt = t.elapsed().as_secs_f64();
    println!(
        "tree evaluation (1 thread): {:.0} ns per point for all {} functions ({:.2} ns per function value), {:.2} nodes visited on average; max deviation from inverse transform {:.2e} (checksum {sink:.3})",
        dt / cells.len() as f64 * 1e9,
        tree.functions(),
        dt / (cells.len() * tree.functions()) as f64 * 1e9,
        visited as f64 / cells.len() as f64,
        worst
    );
    println!("total {:.1} s", t_all.elapsed().as_secs_f64());
    Ok(())
}
