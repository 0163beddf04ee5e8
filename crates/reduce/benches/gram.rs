//! Gram accumulation benchmark: `reduce::gram_matrix` on a seeded random `f32` matrix of
//! the corpus shape (96 materials × 4,374,000 values), median of repeated runs. Compare with
//! `python3 tools/reduce/gram_numpy.py` (numpy `Y.T @ Y` on the same shape).
//!
//! `cargo bench -p reduce --bench gram -- [REPEATS] [kernels] [rows=N]`: with `kernels`, every
//! kernel the CPU supports is timed, not only the selected one; `rows=N` times `N` rows instead
//! of 96, over `min(4,374,000, 4·10⁸ / N)` values each (where the choice between the
//! register-tiled kernels and the blocked product is made, see `reduce::BLOCKED_ROWS`). Besides the wall time, the process's
//! CPU time (user + system, from `/proc/self/stat`) per run is printed: on a shared machine it
//! shows how much work the run needed, whatever share of the cores it got.

use std::time::Instant;

use rand::SeedableRng;
use rand_distr::{Distribution, StandardNormal};
use rayon::prelude::*;
use reduce::{gram_matrix_with, GramKernel};

const ROWS: usize = 96;
const DIM: usize = 3 * 90 * 90 * 180;

fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(|a, b| a.total_cmp(b));
    v[v.len() / 2]
}

/// CPU time (user + system) of this process in seconds, `NaN` where `/proc` is unavailable.
fn cpu_seconds() -> f64 {
    brdf::cpu_seconds().unwrap_or(f64::NAN)
}

fn main() {
    let repeats: usize = std::env::args()
        .skip(1)
        .find_map(|a| a.parse().ok())
        .unwrap_or(5);
    let all = std::env::args().any(|a| a == "kernels");
    let n_rows = std::env::args()
        .find_map(|a| a.strip_prefix("rows=").and_then(|v| v.parse().ok()))
        .unwrap_or(ROWS);
    const N_VALUES: usize = 400_000_000;
    #[allow(non_snake_case)]
    let (N, D) = (n_rows, DIM.min(N_VALUES / n_rows.max(1)));
    let selected = GramKernel::for_rows(N);
    let kernels: Vec<GramKernel> = if all {
        [
            GramKernel::Avx512,
            GramKernel::Avx2,
            GramKernel::Portable,
            GramKernel::Blocked,
        ]
        .into_iter()
        .filter(|k| k.is_available())
        .collect()
    } else {
        vec![selected]
    };
    // Seeded, generated in parallel chunks (one ChaCha stream per chunk).
    let mut data = vec![0.0f32; N * D];
    data.par_chunks_mut(1 << 20)
        .enumerate()
        .for_each(|(c, chunk)| {
            let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(1000 + c as u64);
            for v in chunk {
                *v = StandardNormal.sample(&mut rng);
            }
        });
    let mean = reduce::column_means(&data, N, D).unwrap();
    for &kernel in &kernels {
        for (label, m) in [
            ("Y^T Y (raw)", None),
            ("centred (as used by PCA)", Some(mean.as_slice())),
        ] {
            let run = || gram_matrix_with(&data, N, D, m, kernel).unwrap();
            let _ = run(); // warm-up
            let (times, cpu): (Vec<f64>, Vec<f64>) = (0..repeats)
                .map(|_| {
                    let c = cpu_seconds();
                    let t = Instant::now();
                    std::hint::black_box(run());
                    (t.elapsed().as_secs_f64(), cpu_seconds() - c)
                })
                .unzip();
            let shown: Vec<String> = times.iter().map(|t| format!("{t:.3}")).collect();
            println!(
                "reduce gram {label}, kernel {kernel:?}{}: {N} x {D} f32, {} threads: median {:.4} s over {repeats} ({}); CPU time median {:.2} s",
                if kernel == selected { " (selected)" } else { "" },
                rayon::current_num_threads(),
                median(times.clone()),
                shown.join(", "),
                median(cpu)
            );
        }
    }
}
