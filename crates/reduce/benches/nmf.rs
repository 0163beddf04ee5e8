//! NMF benchmark on the corpus: the 96 shared MERL materials decoded to full 90 × 90 × 180 × 3
//! tables (all 4,374,000 bins kept, linear BRDF values, the decoder's negative values clamped to
//! 0), as `f32`.
//!
//! * `cargo bench -p reduce --bench nmf -- corpus [REPEATS] [TOLERANCE] [MAX_ITERATIONS]
//!   [STRIDE] [convergence-only]`:
//!   time per iteration (median of REPEATS runs of 5 iterations, set-up and the final error pass
//!   included) for the divergence updates at ranks 5, 10 and 20 and HALS at rank 10, then time
//!   and iterations to convergence (relative decrease of the objective below TOLERANCE), on
//!   every STRIDE-th bin (default 1: all). Wall and CPU time (user + system) are printed: on a
//!   shared machine the CPU time shows the work done whatever share of the cores the run got.
//! * `cargo bench -p reduce --bench nmf -- peer DIR STRIDE RANK ITERATIONS REPEATS`: writes the
//!   corpus restricted to every STRIDE-th bin and a seeded initialisation to DIR, runs the
//!   divergence updates from it (median of REPEATS runs) and writes the factors and timings for
//!   `tools/reduce/nmf_sklearn.py`, which runs scikit-learn on the same files.

use std::io::Write;
use std::path::Path;
use std::time::Instant;

use reduce::{nmf_from, random_init, NmfConfig, Solver};

fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(|a, b| a.total_cmp(b));
    v[v.len() / 2]
}

/// CPU time (user + system) of this process in seconds, `NaN` where `/proc` is unavailable.
fn cpu_seconds() -> f64 {
    brdf::cpu_seconds().unwrap_or(f64::NAN)
}

/// Every `stride`-th bin of each material.
fn subsample(n: usize, full: usize, y: Vec<f32>, stride: usize) -> (usize, Vec<f32>) {
    if stride <= 1 {
        return (full, y);
    }
    let dim = full.div_ceil(stride);
    let mut ys = Vec::with_capacity(n * dim);
    for i in 0..n {
        ys.extend(y[i * full..(i + 1) * full].iter().step_by(stride));
    }
    (dim, ys)
}

fn load_corpus() -> (usize, usize, Vec<f32>) {
    let dir = brdf::data_dir().join("nbrdf/merl");
    let names = brdf::nbrdf::list(&dir).unwrap_or_else(|e| {
        panic!("shared data not found ({e}): set BRDF_DATA_DIR to the directory holding nbrdf/merl")
    });
    let t = Instant::now();
    let dim = reduce::MATERIAL_DIM;
    let mut y = Vec::with_capacity(names.len() * dim);
    for name in &names {
        let net = brdf::nbrdf::Nbrdf::load(&dir, name).expect("NBRDF weights");
        y.extend(net.tabulate_f32().into_iter().map(|v| v.max(0.0)));
    }
    let zeros = y.iter().filter(|&&v| v == 0.0).count();
    println!(
        "corpus: {} materials x {dim} bins (linear, f32), decoded in {:.1} s; {:.2} % of the values are 0",
        names.len(),
        t.elapsed().as_secs_f64(),
        100.0 * zeros as f64 / y.len() as f64
    );
    (names.len(), dim, y)
}

fn write_f32(path: &Path, v: &[f32]) {
    let bytes: Vec<u8> = v.iter().flat_map(|x| x.to_le_bytes()).collect();
    brdf::write_atomic(path, &bytes).expect("write");
}

fn write_f64(path: &Path, v: &[f64]) {
    let bytes: Vec<u8> = v.iter().flat_map(|x| x.to_le_bytes()).collect();
    brdf::write_atomic(path, &bytes).expect("write");
}

fn corpus_mode(args: &[String]) {
    let repeats: usize = args.first().and_then(|a| a.parse().ok()).unwrap_or(3);
    let tolerance: f64 = args.get(1).and_then(|a| a.parse().ok()).unwrap_or(1e-3);
    let max_iter: usize = args.get(2).and_then(|a| a.parse().ok()).unwrap_or(300);
    let stride: usize = args.get(3).and_then(|a| a.parse().ok()).unwrap_or(1);
    let skip_timing = args.get(4).is_some_and(|a| a == "convergence-only");
    let (n, full, y) = load_corpus();
    let (dim, y) = subsample(n, full, y, stride);
    if stride > 1 {
        println!("using every {stride}th bin: {n} x {dim}");
    }
    let threads = rayon::current_num_threads();
    let runs = [
        (5, Solver::KullbackLeibler),
        (10, Solver::KullbackLeibler),
        (20, Solver::KullbackLeibler),
        (10, Solver::FrobeniusHals),
    ];
    for &(rank, solver) in runs.iter().filter(|_| !skip_timing) {
        let (u0, x0) = random_init(&y, n, dim, rank, 1).expect("init");
        let cfg = NmfConfig {
            rank,
            iterations: 5,
            tolerance: 0.0,
            seed: 1,
            solver,
        };
        let (times, cpu): (Vec<f64>, Vec<f64>) = (0..repeats)
            .map(|_| {
                let c = cpu_seconds();
                let t = Instant::now();
                let f = nmf_from(&y, n, dim, u0.clone(), x0.clone(), &cfg).expect("nmf");
                std::hint::black_box(f);
                (t.elapsed().as_secs_f64() / 5.0, (cpu_seconds() - c) / 5.0)
            })
            .unzip();
        let shown: Vec<String> = times.iter().map(|t| format!("{t:.3}")).collect();
        println!(
            "nmf {solver:?} rank {rank}: {n} x {dim} f32, {threads} threads: median {:.3} s per iteration over {repeats} runs of 5 ({}); CPU time {:.3} s per iteration",
            median(times),
            shown.join(", "),
            median(cpu)
        );
    }
    for &(rank, solver) in &runs {
        let (u0, x0) = random_init(&y, n, dim, rank, 1).expect("init");
        let cfg = NmfConfig {
            rank,
            iterations: max_iter,
            tolerance,
            seed: 1,
            solver,
        };
        let c = cpu_seconds();
        let t = Instant::now();
        let f = nmf_from(&y, n, dim, u0, x0, &cfg).expect("nmf");
        let secs = t.elapsed().as_secs_f64();
        let cpu = cpu_seconds() - c;
        println!(
            "nmf {solver:?} rank {rank}: {} (tolerance {tolerance:e}) after {} iterations in {secs:.1} s ({:.3} s/iteration; CPU time {cpu:.1} s); objective {:.5e} -> {:.5e}; relative Frobenius error {:.4}",
            if f.converged { "converged" } else { "stopped at the iteration limit" },
            f.iterations,
            secs / f.iterations as f64,
            f.objective[0],
            f.objective[f.iterations],
            f.relative_error
        );
    }
}

fn peer_mode(args: &[String]) {
    let dir = Path::new(
        args.first()
            .expect("peer DIR STRIDE RANK ITERATIONS REPEATS"),
    );
    let num =
        |k: usize, d: usize| -> usize { args.get(k).and_then(|a| a.parse().ok()).unwrap_or(d) };
    let (stride, rank, iters, repeats) = (num(1, 4), num(2, 10), num(3, 50), num(4, 3));
    let (n, full, y) = load_corpus();
    let (dim, ys) = subsample(n, full, y, stride);
    std::fs::create_dir_all(dir).expect("peer directory");
    let (u0, x0) = random_init(&ys, n, dim, rank, 1).expect("init");
    // Both sides start from the same f32 values.
    let x0: Vec<f64> = x0.iter().map(|&v| v as f32 as f64).collect();
    write_f32(&dir.join("y.f32"), &ys);
    write_f32(&dir.join("u0.f32"), &u0);
    let x0f: Vec<f32> = x0.iter().map(|&v| v as f32).collect();
    write_f32(&dir.join("x0.f32"), &x0f);
    let cfg = NmfConfig {
        rank,
        iterations: iters,
        tolerance: 0.0,
        seed: 1,
        solver: Solver::KullbackLeibler,
    };
    let mut times = Vec::new();
    let mut cpu = Vec::new();
    let mut last = None;
    for _ in 0..repeats {
        let c = cpu_seconds();
        let t = Instant::now();
        let f = nmf_from(&ys, n, dim, u0.clone(), x0.clone(), &cfg).expect("nmf");
        times.push(t.elapsed().as_secs_f64());
        cpu.push(cpu_seconds() - c);
        last = Some(f);
    }
    let f = last.expect("at least one repeat");
    write_f32(&dir.join("u.f32"), &f.basis);
    write_f64(&dir.join("x.f64"), &f.weights);
    let shown: Vec<String> = times.iter().map(|t| format!("{t:.3}")).collect();
    let meta = format!(
        "{{\"n\": {n}, \"dim\": {dim}, \"stride\": {stride}, \"rank\": {rank}, \"iterations\": {iters}, \"threads\": {}, \"median_s\": {}, \"cpu_median_s\": {}, \"times_s\": [{}], \"objective\": {}}}\n",
        rayon::current_num_threads(),
        median(times.clone()),
        median(cpu),
        shown.join(", "),
        f.objective[iters]
    );
    brdf::write_atomic(&dir.join("rust.json"), meta.as_bytes()).expect("write");
    let mut out = std::io::stdout().lock();
    writeln!(
        out,
        "reduce nmf (KL, rank {rank}, {iters} iterations) on {n} x {dim} f32 (every {stride}th bin): median {:.3} s over {repeats} ({}); objective {:.6e}",
        median(times),
        shown.join(", "),
        f.objective[iters]
    )
    .expect("stdout");
}

/// Seeded synthetic data of the corpus's magnitude (a low-rank product times noise).
fn synthetic_mode(args: &[String]) {
    use rand::{Rng, SeedableRng};
    use rayon::prelude::*;
    let num =
        |k: usize, d: usize| -> usize { args.get(k).and_then(|a| a.parse().ok()).unwrap_or(d) };
    let (n, dim, rank, iters) = (num(0, 96), num(1, 546_750), num(2, 10), num(3, 10));
    let mut y = vec![0.0f32; n * dim];
    y.par_chunks_mut(dim).enumerate().for_each(|(i, row)| {
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(i as u64);
        let w: Vec<f32> = (0..4).map(|_| rng.gen_range(0.0..1.0)).collect();
        for (d, v) in row.iter_mut().enumerate() {
            let base = w[d % 4] * (1.0 + (d % 97) as f32 * 0.1);
            *v = base * rng.gen_range(0.5..1.5f32);
        }
    });
    let (u0, x0) = random_init(&y, n, dim, rank, 1).expect("init");
    for solver in [Solver::KullbackLeibler, Solver::FrobeniusHals] {
        let cfg = NmfConfig {
            rank,
            iterations: iters,
            tolerance: 0.0,
            seed: 1,
            solver,
        };
        let c = cpu_seconds();
        let t = Instant::now();
        let f = nmf_from(&y, n, dim, u0.clone(), x0.clone(), &cfg).expect("nmf");
        println!(
            "synthetic {n} x {dim}, {solver:?} rank {rank}: {iters} iterations in {:.2} s, CPU time {:.2} s ({:.2} ns per value and iteration); objective {:.4e}",
            t.elapsed().as_secs_f64(),
            cpu_seconds() - c,
            1e9 * (cpu_seconds() - c) / (iters as f64 * (n * dim) as f64),
            f.objective[iters]
        );
    }
}

fn main() {
    let args: Vec<String> = std::env::args()
        .skip(1)
        .filter(|a| a != "--bench")
        .collect();
    match args.first().map(String::as_str) {
        Some("peer") => peer_mode(&args[1..]),
        Some("synthetic") => synthetic_mode(&args[1..]),
        Some("corpus") | None => corpus_mode(args.get(1..).unwrap_or(&[])),
        Some(other) => panic!("unknown mode {other}: use `corpus` or `peer`"),
    }
}
