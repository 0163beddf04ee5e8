#!/usr/bin/env python3
"""scikit-learn side of the NMF benchmark of the `reduce` crate, and the comparison.

Runs `cargo bench -p reduce --bench nmf -- peer DIR STRIDE RANK ITERATIONS REPEATS`, which
decodes the 96 shared MERL materials, keeps every STRIDE-th bin (all 4,374,000 with STRIDE 1),
writes the data and a seeded initialisation to DIR, runs `reduce::nmf` (Kullback-Leibler
multiplicative updates) from it and writes its factors and timings. Then runs scikit-learn's
`non_negative_factorization(beta_loss='kullback-leibler', solver='mu', init='custom', tol=0)`
from the same float32 initialisation for the same number of iterations, evaluates the
divergence of both results in float64 with the same numpy code, and prints the time ratio
(reduce / scikit-learn) and the relative difference of the objectives.

    pip install numpy scikit-learn threadpoolctl
    env -u OPENBLAS_CORETYPE -u OPENBLAS_L2_SIZE python3 tools/reduce/nmf_sklearn.py \
        [--stride 4] [--rank 10] [--iterations 50] [--repeats 3]
"""
import argparse
import json
import os
import statistics
import subprocess
import sys
import tempfile
import time
import warnings

import numpy as np
from sklearn.decomposition import non_negative_factorization
from threadpoolctl import threadpool_info


def kl_divergence(y, w, h, chunk=65536):
    """Generalised KL divergence of y (n x d) from w @ h, in float64, by column chunks."""
    w = w.astype(np.float64)
    total = 0.0
    for c0 in range(0, y.shape[1], chunk):
        yc = y[:, c0:c0 + chunk].astype(np.float64)
        m = w @ h[:, c0:c0 + chunk].astype(np.float64)
        pos = yc > 0
        total += float(np.sum(yc[pos] * np.log(yc[pos] / m[pos]) - yc[pos]) + np.sum(m))
    return total


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--stride", type=int, default=4)
    ap.add_argument("--rank", type=int, default=10)
    ap.add_argument("--iterations", type=int, default=50)
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--dir", default=None, help="work directory (default: a temporary one)")
    a = ap.parse_args()
    root = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
    with tempfile.TemporaryDirectory(prefix="nmf-peer-") as tmp:
        d = a.dir or tmp
        cmd = ["cargo", "bench", "-p", "reduce", "--bench", "nmf", "--", "peer", d,
               str(a.stride), str(a.rank), str(a.iterations), str(a.repeats)]
        print("$", " ".join(cmd), flush=True)
        subprocess.run(cmd, cwd=root, check=True)
        meta = json.load(open(os.path.join(d, "rust.json")))
        n, dim, r = meta["n"], meta["dim"], meta["rank"]
        y = np.fromfile(os.path.join(d, "y.f32"), dtype="<f4").reshape(n, dim)
        u0 = np.fromfile(os.path.join(d, "u0.f32"), dtype="<f4").reshape(dim, r)
        x0 = np.fromfile(os.path.join(d, "x0.f32"), dtype="<f4").reshape(r, n)
        u = np.fromfile(os.path.join(d, "u.f32"), dtype="<f4").reshape(dim, r)
        x = np.fromfile(os.path.join(d, "x.f64"), dtype="<f8").reshape(r, n)
        # scikit-learn: X (n_samples x n_features) ~ W H, so X = y, W = x^T, H = u^T.
        w0 = np.ascontiguousarray(x0.T)
        h0 = np.ascontiguousarray(u0.T)
        blas = [(i["internal_api"], i.get("version"), i.get("architecture"), i["num_threads"])
                for i in threadpool_info() if i["user_api"] == "blas"]
        times, cpu = [], []
        for _ in range(a.repeats):
            c = time.process_time()
            t = time.perf_counter()
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")
                w, h, it = non_negative_factorization(
                    y, W=w0.copy(), H=h0.copy(), n_components=r, init="custom",
                    update_H=True, solver="mu", beta_loss="kullback-leibler", tol=0.0,
                    max_iter=a.iterations, alpha_W=0.0, alpha_H=0.0)
            times.append(time.perf_counter() - t)
            cpu.append(time.process_time() - c)
            assert it == a.iterations, it
        sk = statistics.median(times)
        start = kl_divergence(y, w0, h0)
        ours = kl_divergence(y, x.T, u.T)
        theirs = kl_divergence(y, w, h)
        print(f"data: {n} x {dim} float32 (every {a.stride}th bin of the corpus), rank {r}, "
              f"{a.iterations} iterations, same float32 initialisation")
        print(f"scikit-learn {__import__('sklearn').__version__}, numpy {np.__version__}, BLAS {blas}")
        print(f"reduce::nmf:   median {meta['median_s']:.3f} s over {a.repeats} ({meta['times_s']}), "
              f"{meta['threads']} threads; CPU time median {meta['cpu_median_s']:.2f} s")
        print(f"scikit-learn:  median {sk:.3f} s over {a.repeats} "
              f"({', '.join(f'{t:.3f}' for t in times)}); CPU time median {statistics.median(cpu):.2f} s")
        print(f"ratio (reduce / scikit-learn): wall {meta['median_s'] / sk:.3f}, "
              f"CPU time {meta['cpu_median_s'] / statistics.median(cpu):.3f}")
        print(f"KL divergence (float64, same numpy code): start {start:.6e}; "
              f"reduce {ours:.6e}; scikit-learn {theirs:.6e}; "
              f"relative difference {abs(ours - theirs) / theirs:.2e}")
        print(f"reduce's own figure of its objective: {meta['objective']:.6e} "
              f"(relative to the float64 evaluation {meta['objective'] / ours - 1:.2e})")
        ok = abs(ours - theirs) <= 0.01 * theirs
        print("objectives agree within 1 %" if ok else "objectives differ by more than 1 %")
        return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())
