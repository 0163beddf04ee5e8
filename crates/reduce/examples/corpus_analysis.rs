//! Full analysis of the shared corpus (the figures of docs/reduce.md): PCA eigenvalues and error curves
//! of the 96 MERL materials, reconstruction errors of the 8 Nielsen materials at K = 5, 10, 20,
//! 45, the charting error against embedding dimension 1..20, the long-move plausibility test
//! (thesis Fig. 4-7), NMF runtime, and the report (CSV + PNG) of the model.
//!
//! `cargo run --release -p reduce --example corpus_analysis -- [OUT_DIR] [--nmf-iters N]
//! [--skip-nmf] [--save-model PATH] [--model PATH]` (`--model` reuses a model file built from
//! the same corpus instead of recomputing the PCA).
//! (default `target/reduce-analysis`; `BRDF_DATA_DIR` overrides the data location).

use std::path::PathBuf;
use std::time::Instant;

use reduce::write_report;
use reduce::ChartingConfig;
use reduce::{build_model, chart_pca_coords};
use reduce::{from_log, Corpus};
use reduce::{
    highlight_hole_fraction, long_move_comparison, median_by_step, move_pairs, Reference,
};
use reduce::{nmf, NmfConfig};

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let out = args
        .iter()
        .find(|a| !a.starts_with("--"))
        .map(PathBuf::from)
        .unwrap_or_else(|| "target/reduce-analysis".into());
    let nmf_iters: usize = args
        .iter()
        .position(|a| a == "--nmf-iters")
        .and_then(|i| args.get(i + 1))
        .map(|s| s.parse())
        .transpose()?
        .unwrap_or(20);
    let skip_nmf = args.iter().any(|a| a == "--skip-nmf");
    std::fs::create_dir_all(&out)?;
    let data = brdf::data_dir();
    let t = Instant::now();
    let corpus = Corpus::from_nbrdf_dir(data.join("nbrdf/merl"))?;
    println!(
        "corpus: {} materials × {} values, decoded in {:.1} s",
        corpus.len(),
        corpus.dim(),
        t.elapsed().as_secs_f64()
    );

    let t = Instant::now();
    let model = match args
        .iter()
        .position(|a| a == "--model")
        .and_then(|i| args.get(i + 1))
    {
        Some(p) => {
            let m = reduce::Model::load(p)?;
            if m.names != corpus.names() {
                return Err(format!("{p} was not built from this corpus").into());
            }
            println!("model loaded from {p}: {:.1} s", t.elapsed().as_secs_f64());
            m
        }
        None => {
            let m = build_model(&corpus, 60, Some(15), Some(45))?;
            println!(
                "PCA (Gram + eigen + 60 components) and 15-D chart: {:.1} s",
                t.elapsed().as_secs_f64()
            );
            m
        }
    };
    let ev = &model.pca.eigenvalues;
    let curve = reduce::residual_curve(ev);
    println!("\n# eigenvalues (first 60) and relative residual sqrt(Σ_{{j>k}} λ / Σ λ)");
    println!("k\teigenvalue\tresidual_after_k");
    for k in 0..60.min(ev.len()) {
        println!("{}\t{:.6e}\t{:.5}", k + 1, ev[k], curve[k + 1]);
    }

    println!(
        "\n# Nielsen materials (not in the corpus): relative error ‖y−ỹ‖/‖y−m‖ (RMS log error)"
    );
    let ks = [5usize, 10, 20, 45];
    println!("material\tK=5\tK=10\tK=20\tK=45");
    let nielsen_dir = data.join("nbrdf/nielsen");
    for name in brdf::nbrdf::list(&nielsen_dir)? {
        let v: Vec<f64> = brdf::nbrdf::Nbrdf::load(&nielsen_dir, &name)?
            .tabulate_f32()
            .iter()
            .map(|&x| x as f64)
            .collect();
        let e = model.reconstruction_errors(&v, &ks)?;
        let cells: Vec<String> = e
            .iter()
            .map(|r| format!("{:.4} ({:.4})", r.relative, r.rms_log))
            .collect();
        println!("{name}\t{}", cells.join("\t"));
    }

    // Norms for expressing chart errors relative to the uncentred log vectors.
    let total_centred: f64 = ev.iter().sum();
    let mean_sq: f64 = model
        .pca
        .mean
        .iter()
        .map(|&v| (v as f64) * (v as f64))
        .sum();
    let total_uncentred = total_centred + corpus.len() as f64 * mean_sq;
    println!(
        "\n# ‖centred corpus‖² = {total_centred:.4e}, ‖uncentred log corpus‖² = {total_uncentred:.4e} (ratio {:.4})",
        total_centred / total_uncentred
    );
    let pca_unexplained = |k: usize| ev.iter().skip(k).sum::<f64>() / total_centred;
    for kc in [45usize, 60] {
        println!(
            "\n# charting in the first {kc} PCA coordinates: reconstruction error vs dimension"
        );
        println!("# r = Σ‖ŷ−y‖² over the 96 training points in those coordinates. Columns: (r + Σ_{{j≥{kc}}} λ)/Σλ [adopted]; its sqrt; sqrt(r/centred); r/centred; sqrt(r/uncentred); PCA Σ_{{j≥d}} λ/Σλ");
        println!("d\tunexpl_total\trel_total\trel_coords\tunexpl_coords\trel_uncentred\tpca_unexpl_k=d\tseconds");
        let t0 = Instant::now();
        let charts = reduce::Charts::fit(
            &model.pca.coords.columns(0, kc).into_owned(),
            ChartingConfig::default(),
        )?;
        println!(
            "# sigma = {:.4}, charts fitted in {:.2} s",
            charts.sigma,
            t0.elapsed().as_secs_f64()
        );
        for d in 1..=20 {
            let t = Instant::now();
            match charts
                .connect(d)
                .and_then(|c| reduce::chart_errors(&model.pca, &c))
            {
                Ok(e) => println!(
                    "{d}\t{:.5}\t{:.5}\t{:.5}\t{:.5}\t{:.5}\t{:.5}\t{:.2}",
                    e.unexplained_total,
                    e.relative_total,
                    e.relative_in_coords,
                    e.unexplained_in_coords,
                    e.relative_uncentred,
                    pca_unexplained(d),
                    t.elapsed().as_secs_f64()
                ),
                Err(e) => println!("{d}\tfailed: {e}"),
            }
        }
    }

    println!("\n# held-out materials (leave one out, 45 PCA coordinates): chart of the other 95 vs their d-dimensional PCA");
    println!("d\tchart_relative\tlinear_relative\tchart_better_for");
    let pts45 = model.pca.coords.columns(0, 45).into_owned();
    for d in [5usize, 10, 15] {
        let h = reduce::held_out_errors(&pts45, d, ChartingConfig::default())?;
        println!(
            "{d}\t{:.4}\t{:.4}\t{}/{}",
            h.chart_relative(),
            h.linear_relative(),
            h.chart_better(),
            h.chart.len()
        );
    }

    println!("\n# long moves (thesis Fig. 4-7): 15-D chart in 45 PCA coordinates vs straight line in those 45 coordinates at equal distance");
    let chart = chart_pca_coords(&model.pca, 15, Some(45), ChartingConfig::default())?;
    let reference = Reference::new(&model, &corpus, 45)?;
    let pairs = move_pairs(corpus.len(), 48, 7);
    let t = Instant::now();
    let rows = long_move_comparison(
        &model,
        &chart,
        &reference,
        &pairs,
        &[0.5, 1.0, 1.5, 2.0, 3.0],
    )?;
    println!(
        "# {} pairs (seeded), median nearest-neighbour distance {:.1}; {:.1} s",
        pairs.len(),
        reference.median_nn,
        t.elapsed().as_secs_f64()
    );
    println!("# medians over pairs; columns per model: distance from A, nearest corpus material / median NN distance, negative fraction, outside-range fraction, highlight-hole fraction");
    println!("t\tlinear: dist nearest negative outside holes\tchart: dist nearest negative outside holes\tchart better (nearest, negative, outside, holes)");
    for (t, l, c) in median_by_step(&rows) {
        let sel: Vec<_> = rows.iter().filter(|r| r.t == t).collect();
        let better = |f: &dyn Fn(&reduce::Plausibility) -> f64| {
            sel.iter().filter(|r| f(&r.chart) < f(&r.linear)).count()
        };
        println!(
            "{t:.1}\t{:.0} {:.2} {:.4} {:.4} {:.4}\t{:.0} {:.2} {:.4} {:.4} {:.4}\t{} {} {} {} of {}",
            l.distance,
            l.nearest_material,
            l.negative_fraction,
            l.outside_corpus_range,
            l.highlight_holes,
            c.distance,
            c.nearest_material,
            c.negative_fraction,
            c.outside_corpus_range,
            c.highlight_holes,
            better(&|p| p.nearest_material),
            better(&|p| p.negative_fraction),
            better(&|p| p.outside_corpus_range),
            better(&|p| p.highlight_holes),
            sel.len()
        );
    }
    let base: Vec<f64> = (0..corpus.len())
        .map(|i| {
            let x: Vec<f64> = (0..45).map(|c| model.pca.coords[(i, c)]).collect();
            model
                .pca
                .reconstruct(&x)
                .map(|y| highlight_hole_fraction(&y))
        })
        .collect::<Result<_, _>>()?;
    println!(
        "# highlight-hole fraction of the corpus members themselves (45 components): median {:.4}, max {:.4}",
        {
            let mut b = base.clone();
            b.sort_by(f64::total_cmp);
            b[b.len() / 2]
        },
        base.iter().copied().fold(0.0, f64::max)
    );

    let t = Instant::now();
    write_report(&model, &out)?;
    println!(
        "\nreport written to {} in {:.1} s",
        out.display(),
        t.elapsed().as_secs_f64()
    );

    if let Some(p) = args
        .iter()
        .position(|a| a == "--save-model")
        .and_then(|i| args.get(i + 1))
    {
        let t = Instant::now();
        model.save(p)?;
        println!("model saved to {p} in {:.1} s", t.elapsed().as_secs_f64());
    }
    if skip_nmf {
        return Ok(());
    }
    // NMF in the linear domain (the thesis's future work).
    let (names, dim, mut y) = corpus.into_parts();
    for v in y.iter_mut() {
        *v = from_log(*v).max(0.0) as f32;
    }
    for rank in [5usize, 10] {
        let t = Instant::now();
        let cfg = NmfConfig {
            rank,
            iterations: nmf_iters,
            seed: 1,
            tolerance: 0.0,
            solver: reduce::Solver::KullbackLeibler,
        };
        let f = nmf(&y, names.len(), dim, &cfg)?;
        println!(
            "\nNMF rank {rank}: {nmf_iters} iterations in {:.1} s ({:.2} s/iteration); KL divergence {:.4e} -> {:.4e}; relative Frobenius error {:.4}",
            t.elapsed().as_secs_f64(),
            t.elapsed().as_secs_f64() / nmf_iters as f64,
            f.objective.first().copied().unwrap_or(f64::NAN),
            f.objective.last().copied().unwrap_or(f64::NAN),
            f.relative_error
        );
    }
    Ok(())
}
