//! Gram accumulation benchmark: `reduce::gram::gram_matrix` on a seeded random `f32` matrix of
//! the corpus shape (96 materials × 4,374,000 values), median of repeated runs. Compare with
//! `python3 tools/reduce/gram_numpy.py` (numpy `Y.T @ Y` on the same shape).
//!
//! `cargo bench -p reduce --bench gram -- [REPEATS]`

use std::time::Instant;

use rand::SeedableRng;
use rand_distr::{Distribution, StandardNormal};
use rayon::prelude::*;

const N: usize = 96;
const D: usize = 3 * 90 * 90 * 180;

fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(|a, b| a.total_cmp(b));
    v[v.len() / 2]
}

fn main() {
    let repeats: usize = std::env::args()
        .skip(1)
        .find_map(|a| a.parse().ok())
        .unwrap_or(5);
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
    let mean = reduce::gram::column_means(&data, N, D).unwrap();
    for (label, m) in [
        ("Y^T Y (raw)", None),
        ("centred (as used by PCA)", Some(mean.as_slice())),
    ] {
        let _ = reduce::gram::gram_matrix(&data, N, D, m).unwrap(); // warm-up
        let times: Vec<f64> = (0..repeats)
            .map(|_| {
                let t = Instant::now();
                let g = reduce::gram::gram_matrix(&data, N, D, m).unwrap();
                std::hint::black_box(g);
                t.elapsed().as_secs_f64()
            })
            .collect();
        let shown: Vec<String> = times.iter().map(|t| format!("{t:.3}")).collect();
        println!(
            "reduce gram {label}: {N} x {D} f32, {} threads: median {:.4} s over {repeats} ({})",
            rayon::current_num_threads(),
            median(times.clone()),
            shown.join(", ")
        );
    }
}
