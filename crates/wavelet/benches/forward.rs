//! Forward 3D nonstandard transform of a 256³ f32 cube (full 8-level decomposition), the
//! configuration of thesis §6.2, timed as the median of repeated runs.
//!
//! Compare with `python3 tools/wavelet/bench_pywt.py` (PyWavelets `wavedecn`, same input
//! formula, same number of levels). Run: `cargo bench -p wavelet --bench forward`.
//! Options (after `--`): `--runs N` (default 11), `--threads T` (default: rayon's default).

use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use std::time::Instant;
use wavelet::{forward_full, inverse_full, Cube, Wavelet};

fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(f64::total_cmp);
    v[v.len() / 2]
}

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let get = |flag: &str| {
        args.iter()
            .position(|a| a == flag)
            .and_then(|i| args.get(i + 1))
            .and_then(|v| v.parse::<usize>().ok())
    };
    let runs = get("--runs").unwrap_or(11);
    if let Some(t) = get("--threads") {
        rayon::ThreadPoolBuilder::new()
            .num_threads(t)
            .build_global()
            .expect("thread pool");
    }
    let side = 256;
    let mut rng = ChaCha8Rng::seed_from_u64(1);
    let data: Vec<f32> = (0..side * side * side)
        .map(|_| rng.gen_range(0.0f32..1.0))
        .collect();
    let base = Cube::from_vec(side, data).expect("cube");
    println!(
        "256^3 f32 cube, full 8-level nonstandard decomposition, {} rayon threads, {runs} runs",
        rayon::current_num_threads()
    );
    println!("{:<8} {:>14} {:>14}", "wavelet", "forward_ms", "inverse_ms");
    for w in Wavelet::ALL {
        let mut fwd = Vec::with_capacity(runs);
        let mut inv = Vec::with_capacity(runs);
        let mut c = base.clone();
        for _ in 0..runs {
            c.data_mut().copy_from_slice(base.data());
            let t = Instant::now();
            forward_full(&mut c, w).expect("forward");
            fwd.push(t.elapsed().as_secs_f64() * 1e3);
            let t = Instant::now();
            inverse_full(&mut c, w).expect("inverse");
            inv.push(t.elapsed().as_secs_f64() * 1e3);
        }
        println!(
            "{:<8} {:>14.1} {:>14.1}",
            w.name(),
            median(fwd),
            median(inv)
        );
    }
}
