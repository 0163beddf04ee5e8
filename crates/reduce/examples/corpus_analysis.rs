//! Full analysis of the shared corpus (issue 7 "Done when"): PCA eigenvalues and error curves
//! of the 96 MERL materials, reconstruction errors of the 8 Nielsen materials at K = 5, 10, 20,
//! 45, the charting error against embedding dimension 1..20, the long-move plausibility test
//! (seed Fig. 4-7), NMF runtime, and the report (CSV + PNG) of the model.
//!
//! `cargo run --release -p reduce --example corpus_analysis -- [OUT_DIR] [--nmf-iters N]`
//! (default `target/reduce-analysis`; `BRDF_DATA_DIR` overrides the data location).

use std::path::PathBuf;
use std::time::Instant;

use reduce::charting::ChartingConfig;
use reduce::corpus::{from_log, Corpus};
use reduce::model::{build_model, chart_pca_coords};
use reduce::nmf::{nmf, NmfConfig};
use reduce::plausibility::long_move_comparison;
use reduce::report::write_report;

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
    let model = build_model(&corpus, 60, Some(15), Some(45))?;
    println!(
        "PCA (Gram + eigen + 60 components) and 15-D chart: {:.1} s",
        t.elapsed().as_secs_f64()
    );
    let ev = &model.pca.eigenvalues;
    let curve = reduce::pca::residual_curve(ev);
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
    for kc in [45usize, 60] {
        let sub: f64 = ev[..kc].iter().sum();
        let rest: f64 = ev[kc..].iter().sum();
        println!(
            "\n# charting in the first {kc} PCA coordinates: reconstruction error vs dimension"
        );
        println!("# columns: error relative to the centred corpus in those coordinates; relative to the uncentred log vectors (chart only); same including the PCA truncation to {kc} coordinates");
        println!("d\trel_centred\trel_uncentred\trel_uncentred_total\tseconds");
        let t0 = Instant::now();
        let charts = reduce::charting::Charts::fit(
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
            match charts.connect(d).and_then(|c| c.reconstruction_error()) {
                Ok(e) => println!(
                    "{d}\t{e:.5}\t{:.5}\t{:.5}\t{:.2}",
                    (e * e * sub / total_uncentred).sqrt(),
                    ((e * e * sub + rest) / total_uncentred).sqrt(),
                    t.elapsed().as_secs_f64()
                ),
                Err(e) => println!("{d}\tfailed: {e}"),
            }
        }
    }

    for tol in [1e-12, 1e-2, 1e-1] {
        println!("\n# long move (seed Fig. 4-7): linear 45-D PCA vs 15-D chart (pseudo-inverse tolerance {tol:e})");
        let cfg = ChartingConfig {
            pinv_tolerance: tol,
            ..ChartingConfig::default()
        };
        let chart = chart_pca_coords(&model.pca, 15, Some(45), cfg)?;
        let rows = long_move_comparison(&model, &chart, &corpus, 45)?;
        println!("pair\tt\tlinear: distance negative outside_range\tchart: distance negative outside_range");
        for r in rows {
            println!(
                "{}->{}\t{:.1}\t{:.0} {:.4} {:.4}\t{:.0} {:.4} {:.4}",
                r.from,
                r.to,
                r.t,
                r.linear.distance,
                r.linear.negative_fraction,
                r.linear.outside_corpus_range,
                r.chart.distance,
                r.chart.negative_fraction,
                r.chart.outside_corpus_range
            );
        }
    }

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
    // NMF in the linear domain (the seed's future work).
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
            track_divergence: false,
        };
        let f = nmf(&y, names.len(), dim, &cfg)?;
        println!(
            "\nNMF rank {rank}: {nmf_iters} iterations in {:.1} s ({:.2} s/iteration); KL divergence {:.4e} -> {:.4e}; relative Frobenius error {:.4}",
            t.elapsed().as_secs_f64(),
            t.elapsed().as_secs_f64() / nmf_iters as f64,
            f.divergence.first().copied().unwrap_or(f64::NAN),
            f.divergence.last().copied().unwrap_or(f64::NAN),
            f.relative_error
        );
    }
    Ok(())
}
