//! What a model of the shared corpus costs: building it (`gantry model build` without the chart)
//! and decoding one material from its coordinates (the editor does it per slider move), for
//! each mapping. Medians of repeated runs, with the process's CPU time beside the wall time.
//!
//! `cargo bench -p reduce --bench model_cost -- [BUILDS] [DECODES]` (defaults 3 and 11) reads
//! the 96 MERL materials from `$BRDF_DATA_DIR/nbrdf/merl` (default `../shared/data`); without
//! them it stops with an error naming the folder.

use std::time::Instant;

use reduce::{build_mapped_model, Corpus, Mapping};

fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(|a, b| a.total_cmp(b));
    v[v.len() / 2]
}

/// Wall and CPU seconds of `f`, and its result.
fn timed<T>(f: impl FnOnce() -> T) -> (f64, f64, T) {
    let (t, c) = (Instant::now(), brdf::cpu_seconds().unwrap_or(f64::NAN));
    let out = f();
    (
        t.elapsed().as_secs_f64(),
        brdf::cpu_seconds().unwrap_or(f64::NAN) - c,
        out,
    )
}

fn main() {
    let numbers: Vec<usize> = std::env::args()
        .skip(1)
        .filter_map(|a| a.parse().ok())
        .collect();
    let builds = numbers.first().copied().unwrap_or(3).max(1);
    let decodes = numbers.get(1).copied().unwrap_or(11).max(1);
    let dir = brdf::data_dir().join("nbrdf/merl");
    let (wall, cpu, corpus) = timed(|| Corpus::from_nbrdf_dir(&dir));
    let corpus = match corpus {
        Ok(c) => c,
        Err(e) => {
            eprintln!(
                "model_cost: cannot read the corpus at {} ({e}); set BRDF_DATA_DIR",
                dir.display()
            );
            std::process::exit(1);
        }
    };
    println!(
        "corpus: {} materials decoded in {wall:.1} s (CPU {cpu:.1} s); threads: {}",
        corpus.len(),
        rayon::current_num_threads()
    );
    println!("| mapping | build, 60 components (s) | CPU (s) | decode k = 10 (ms) | decode k = 45 (ms) | of which the linear part, k = 45 (ms) | decoder of 45: build (s) | decoder: k = 10 (ms) | decoder: k = 45 (ms) | decoder vs synthesize: max \\|Δ ln f\\| |");
    println!("|---|---|---|---|---|---|---|---|---|---|");
    for mapping in [Mapping::Log, Mapping::COSINE] {
        let mut build_wall = Vec::new();
        let mut build_cpu = Vec::new();
        let mut model = None;
        for _ in 0..builds {
            let (w, c, m) = timed(|| build_mapped_model(&corpus, mapping, 60, None, None));
            build_wall.push(w);
            build_cpu.push(c);
            model = Some(m.expect("model"));
        }
        let model = model.expect("at least one build");
        let decode = |k: usize, linear_only: bool| -> f64 {
            let times: Vec<f64> = (0..decodes)
                .map(|i| {
                    let row = i % model.names.len();
                    let x: Vec<f64> = (0..k).map(|j| model.pca.coords[(row, j)]).collect();
                    let (w, _, out) = timed(|| {
                        if linear_only {
                            model.pca.reconstruct(&x).map(|v| v.len())
                        } else {
                            model.synthesize(&x).map(|v| v.len())
                        }
                    });
                    assert_eq!(out.expect("decode"), brdf::MATERIAL_DIM);
                    w
                })
                .collect();
            1e3 * median(times)
        };
        // the interactive decoder: half-precision, component-major (`Model::decoder`)
        let (decoder_build, _, decoder) = timed(|| model.decoder(45));
        let decoder = decoder.expect("decoder");
        let mut out = vec![0.0; brdf::MATERIAL_DIM];
        let fast = |k: usize, out: &mut Vec<f64>| -> f64 {
            let times: Vec<f64> = (0..decodes)
                .map(|i| {
                    let row = i % model.names.len();
                    let x: Vec<f64> = (0..k).map(|j| model.pca.coords[(row, j)]).collect();
                    let (w, _, r) = timed(|| decoder.decode_into(&x, out));
                    r.expect("decode");
                    w
                })
                .collect();
            1e3 * median(times)
        };
        let (fast10, fast45) = (fast(10, &mut out), fast(45, &mut out));
        // the largest log difference from the exact decode, over every corpus material
        let (floor, weights) = mapping.inverse_form();
        let w = |i: usize| weights.map_or(1.0, |w| w[i % w.len()] as f64);
        let mut worst = 0.0f64;
        for row in 0..model.names.len() {
            let x: Vec<f64> = (0..45).map(|j| model.pca.coords[(row, j)]).collect();
            let exact = model.synthesize(&x).expect("decode");
            decoder.decode_into(&x, &mut out).expect("decode");
            for (i, (a, b)) in out.iter().zip(&exact).enumerate() {
                // in the model's space: z = ln(f w + floor), where neither value was clamped
                if *a > 0.0 && *b > 0.0 {
                    worst = worst.max(((a * w(i) + floor) / (b * w(i) + floor)).ln().abs());
                }
            }
        }
        println!(
            "| {} | {:.1} | {:.1} | {:.0} | {:.0} | {:.0} | {:.2} | {:.0} | {:.0} | {:.1e} |",
            mapping.name(),
            median(build_wall),
            median(build_cpu),
            decode(10, false),
            decode(45, false),
            decode(45, true),
            decoder_build,
            fast10,
            fast45,
            worst,
        );
    }
}
