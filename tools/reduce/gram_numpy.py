#!/usr/bin/env python3
"""numpy side of the Gram benchmark of the `reduce` crate.

Times `Y.T @ Y` for a seeded random float32 matrix Y of shape (D, N) = (4,374,000, 96) — one
column per material, as in the thesis (eq. 4.1) — and, for reference, the same product with the
material-major layout used by `reduce` (`X @ X.T`, X of shape (N, D)). Prints the median of the
repetitions in seconds. Compare with `cargo bench -p reduce --bench gram`.

    pip install numpy
    python3 tools/reduce/gram_numpy.py [REPEATS]
"""
import statistics
import sys
import time

import numpy as np

D = 3 * 90 * 90 * 180
N = 96


def median_time(f, repeats):
    """Median wall time, the wall times, and the median CPU time (user + system, all threads)."""
    f()  # warm-up
    times, cpu = [], []
    for _ in range(repeats):
        c = time.process_time()
        t = time.perf_counter()
        f()
        times.append(time.perf_counter() - t)
        cpu.append(time.process_time() - c)
    return statistics.median(times), times, statistics.median(cpu)


def main():
    repeats = int(sys.argv[1]) if len(sys.argv) > 1 else 5
    rng = np.random.default_rng(1)
    y = rng.standard_normal((D, N), dtype=np.float32)
    try:
        from threadpoolctl import threadpool_info
        blas = [(i["internal_api"], i.get("version"), i.get("architecture"), i["num_threads"])
                for i in threadpool_info() if i["user_api"] == "blas"]
        print(f"BLAS: {blas}")
    except ImportError:
        print("BLAS: (install threadpoolctl to see which kernel runs)")
    med, times, cpu = median_time(lambda: y.T @ y, repeats)
    print(f"numpy {np.__version__}: Y.T @ Y, Y float32 {D} x {N}: median {med:.4f} s over {repeats} ({', '.join(f'{t:.3f}' for t in times)}); CPU time median {cpu:.2f} s")
    x = np.ascontiguousarray(y.T)
    del y
    med, times, cpu = median_time(lambda: x @ x.T, repeats)
    print(f"numpy {np.__version__}: X @ X.T, X float32 {N} x {D}: median {med:.4f} s over {repeats} ({', '.join(f'{t:.3f}' for t in times)}); CPU time median {cpu:.2f} s")


if __name__ == "__main__":
    main()
