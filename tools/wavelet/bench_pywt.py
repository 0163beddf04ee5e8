"""PyWavelets peer benchmark for crates/wavelet/benches/forward.rs.

Times pywt.wavedecn on a 256^3 float32 cube, full 8-level decomposition (mode='periodization', so
every level halves each axis exactly like the Rust transform), and prints the median of N runs.
'haar' is the like-for-like comparison; 'bior2.2' (CDF 5/3) and 'db2' (Daubechies-4) are
given for reference (their boundary handling differs from the Rust lifting versions).

Run:  python3 tools/wavelet/bench_pywt.py [runs]
"""
import os
import statistics
import sys
import time

import warnings

import numpy as np
import pywt


def main():
    warnings.filterwarnings("ignore", message="Level value")
    runs = int(sys.argv[1]) if len(sys.argv) > 1 else 11
    rng = np.random.default_rng(1)
    cube = rng.random((256, 256, 256), dtype=np.float32)
    print(f"pywt {pywt.__version__}, numpy {np.__version__}, cpu count {os.cpu_count()}, {runs} runs")
    print(f"{'wavelet':<8} {'forward_ms':>14} {'inverse_ms':>14}")
    for name in ("haar", "bior2.2", "db2"):
        fwd, inv = [], []
        for _ in range(runs):
            t = time.perf_counter()
            coeffs = pywt.wavedecn(cube, name, mode="periodization", level=8)
            fwd.append((time.perf_counter() - t) * 1e3)
            t = time.perf_counter()
            pywt.waverecn(coeffs, name, mode="periodization")
            inv.append((time.perf_counter() - t) * 1e3)
        assert coeffs[0].dtype == np.float32
        print(f"{name:<8} {statistics.median(fwd):>14.1f} {statistics.median(inv):>14.1f}")


if __name__ == "__main__":
    main()
