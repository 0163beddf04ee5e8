#!/usr/bin/env python3
"""The Gram benchmark of `reduce` against numpy, in one run, with ratios.

Runs `cargo bench -p reduce --bench gram -- REPEATS kernels` (every SIMD kernel this CPU has, on
a seeded 96 x 4,374,000 float32 corpus) and `tools/reduce/gram_numpy.py REPEATS` twice: once
with OpenBLAS choosing its kernel for this CPU, once with `OPENBLAS_CORETYPE=Haswell`, i.e. the
AVX2 + FMA kernels OpenBLAS runs on an AVX2 machine. Each kernel of ours is compared with the
numpy of the same instruction set (AVX-512 with the native OpenBLAS where that is an AVX-512
kernel, AVX2 with Haswell), in wall time and in CPU time (user + system, all threads), medians
of REPEATS runs each. A ratio below 1 means `reduce` is faster; the goal is <= 0.7.

    python3 tools/reduce/gram_compare.py [REPEATS] [--python .venv/bin/python]

numpy's environment is cleared of OPENBLAS_CORETYPE and OPENBLAS_L2_SIZE for the native run
(older OpenBLAS builds on some processors need them set, and they slow a current numpy).
"""
import argparse
import os
import re
import subprocess
import sys

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(os.path.dirname(HERE))

RUST = re.compile(
    r"reduce gram (?P<what>Y\^T Y \(raw\)|centred[^,]*), kernel (?P<kernel>\w+).*?"
    r"median (?P<wall>[\d.]+) s.*CPU time median (?P<cpu>[\d.]+) s")
NUMPY = re.compile(
    r"numpy [\d.]+: (?P<what>Y\.T @ Y|X @ X\.T).*?median (?P<wall>[\d.]+) s.*"
    r"CPU time median (?P<cpu>[\d.]+) s")
BLAS = re.compile(r"BLAS: (?P<blas>.*)")


def run(cmd, env=None):
    print("$ " + " ".join(cmd), flush=True)
    out = subprocess.run(cmd, check=True, capture_output=True, text=True, env=env, cwd=ROOT)
    sys.stdout.write(out.stdout)
    return out.stdout


def numpy_times(python, repeats, coretype):
    env = dict(os.environ)
    env.pop("OPENBLAS_CORETYPE", None)
    env.pop("OPENBLAS_L2_SIZE", None)
    if coretype:
        env["OPENBLAS_CORETYPE"] = coretype
    text = run([python, os.path.join(HERE, "gram_numpy.py"), str(repeats)], env)
    blas = BLAS.search(text)
    times = {m["what"]: (float(m["wall"]), float(m["cpu"])) for m in NUMPY.finditer(text)}
    return (blas["blas"] if blas else "?"), times


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("repeats", nargs="?", type=int, default=5)
    ap.add_argument("--python", default=sys.executable, help="the Python with numpy")
    args = ap.parse_args()
    text = run(["cargo", "bench", "-q", "-p", "reduce", "--bench", "gram", "--",
                str(args.repeats), "kernels"])
    ours = {(m["kernel"], m["what"].startswith("Y")): (float(m["wall"]), float(m["cpu"]))
            for m in RUST.finditer(text)}
    native_blas, native = numpy_times(args.python, args.repeats, None)
    avx2_blas, avx2 = numpy_times(args.python, args.repeats, "Haswell")
    print()
    print("| reduce kernel (raw YᵀY) | numpy (OpenBLAS kernel) | numpy product | wall ours / numpy "
          "| ratio | CPU ours / numpy | ratio |")
    print("|---|---|---|---|---|---|---|")
    for kernel, blas, peer in (("Avx512", native_blas, native), ("Avx2", avx2_blas, avx2)):
        if (kernel, True) not in ours:
            print(f"| {kernel} | not available on this CPU | | | | | |")
            continue
        w, c = ours[(kernel, True)]
        for what, (pw, pc) in peer.items():
            print(f"| {kernel} | {blas} | `{what}` | {w:.3f} s / {pw:.3f} s | {w / pw:.2f} "
                  f"| {c:.2f} s / {pc:.2f} s | {c / pc:.2f} |")


if __name__ == "__main__":
    main()
