#!/usr/bin/env python3
"""Independent check of `gantry eval` on a neural-BRDF material.

Decodes the six .npy weight files with NumPy in float64, straight from the formula in
shared/data/README.md, at random (theta_h, theta_d, phi_d), runs `gantry eval` on the same angles
and prints the largest relative difference.

    python3 tools/nbrdf_check.py ../shared/data/nbrdf/merl blue-acrylic [--n 2000] [--gantry target/release/gantry]
"""
import argparse
import os
import subprocess
import sys
import tempfile

import numpy as np


def decode(d, name, th, td, pd):
    w = {k: np.load(os.path.join(d, f"{name}_{k}.npy")).astype(np.float64)
         for k in ("fc1", "b1", "fc2", "b2", "fc3", "b3")}
    x = np.stack([np.sin(th), np.zeros_like(th), np.cos(th),
                  np.sin(td) * np.cos(pd), np.sin(td) * np.sin(pd), np.cos(td)], axis=1)
    a1 = np.maximum(x @ w["fc1"] + w["b1"], 0.0)
    a2 = np.maximum(a1 @ w["fc2"] + w["b2"], 0.0)
    return np.maximum(np.exp(a2 @ w["fc3"] + w["b3"]) - 1.0, 0.0)


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("dir")
    ap.add_argument("name")
    ap.add_argument("--n", type=int, default=2000)
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--gantry", default="target/release/gantry")
    a = ap.parse_args()
    rng = np.random.default_rng(a.seed)
    th = rng.uniform(0, np.pi / 2, a.n)
    td = rng.uniform(0, np.pi / 2, a.n)
    pd = rng.uniform(0, 2 * np.pi, a.n)
    ref = decode(a.dir, a.name, th, td, pd)
    with tempfile.NamedTemporaryFile("w", suffix=".csv", delete=False) as f:
        f.write("theta_h,theta_d,phi_d\n")
        for row in zip(th, td, pd):
            f.write("%.17g,%.17g,%.17g\n" % row)
        path = f.name
    out = subprocess.run([a.gantry, "eval", f"nbrdf:{a.dir}/{a.name}", "--angles", path],
                         check=True, capture_output=True, text=True).stdout.splitlines()
    os.unlink(path)
    assert out[0] == "theta_h,theta_d,phi_d,r,g,b", out[0]
    got = np.array([[float(v) for v in line.split(",")[3:]] for line in out[1:]])
    # Relative error where the value is not tiny; absolute (scaled by the median) elsewhere.
    scale = np.maximum(np.abs(ref), 1e-3 * np.median(ref[ref > 0]))
    rel = np.abs(got - ref) / scale
    print(f"{a.name}: {a.n} points, max relative difference {rel.max():.3e}, "
          f"median {np.median(rel):.3e}")
    sys.exit(0 if rel.max() <= 1e-4 else 1)


if __name__ == "__main__":
    main()
