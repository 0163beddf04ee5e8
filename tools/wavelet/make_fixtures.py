"""Writes the PyWavelets reference fixtures used by crates/wavelet/tests/transform.rs.

The input cube is defined by a formula that the Rust test reproduces exactly:
    v[x, y, z] = ((37 x + 11 y + 5 z + x*y*z) mod 17) / 17 - 0.5   (float32)
Outputs (little-endian float32, C order, layout of pywt.coeffs_to_array):
    haar16_full.f32  full decomposition (4 levels) of the 16^3 cube
    haar16_l2.f32    two-level decomposition
Run:  python3 tools/wavelet/make_fixtures.py   (needs numpy and PyWavelets)
"""
import pathlib

import numpy as np
import pywt

OUT = pathlib.Path(__file__).resolve().parents[2] / "crates" / "wavelet" / "tests" / "fixtures"


def cube(n):
    x, y, z = np.meshgrid(np.arange(n), np.arange(n), np.arange(n), indexing="ij")
    return (((37 * x + 11 * y + 5 * z + x * y * z) % 17) / 17.0 - 0.5).astype(np.float32)


def mallat(data, level):
    coeffs = pywt.wavedecn(data.astype(np.float64), "haar", mode="periodization", level=level)
    arr, _ = pywt.coeffs_to_array(coeffs)
    return arr.astype("<f4")


def main():
    OUT.mkdir(parents=True, exist_ok=True)
    c = cube(16)
    mallat(c, 4).tofile(OUT / "haar16_full.f32")
    mallat(c, 2).tofile(OUT / "haar16_l2.f32")
    print("wrote fixtures to", OUT)


if __name__ == "__main__":
    main()
