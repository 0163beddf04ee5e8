#!/usr/bin/env python3
"""Independent check of the hdr crate's OpenEXR files with the OpenEXR Python bindings.

Usage: python3 tools/hdr/check_exr.py DIR/hdr/000.exr DIR/truth/000.exr
(pip install OpenEXR numpy). Reads both files with the reference OpenEXR library, prints
channels and header attributes, and the median relative error of `radiance` against the truth
over pixels with valid == 1. Not used by CI.
"""
import sys

import numpy as np
import OpenEXR


def load(path):
    with OpenEXR.File(path) as f:
        part = f.parts[0]
        header = dict(part.header)
        channels = {name: np.asarray(ch.pixels) for name, ch in part.channels.items()}
    return header, channels


def main():
    hdr_path, truth_path = sys.argv[1], sys.argv[2]
    header, ch = load(hdr_path)
    theader, tch = load(truth_path)
    print("channels:", {k: (v.dtype.name, v.shape) for k, v in ch.items()})
    for key in ("hdr_kind", "radiance_units", "exposures_s", "exposure_count", "low_dn",
                "high_dn", "min_correlation", "min_valid", "intercept", "hot_pixels",
                "position", "angle_deg"):
        print(f"  {key} = {header.get(key)!r}")
    print("truth kind:", theader.get("hdr_kind"), "channels:", list(tch))
    assert {"radiance", "valid", "count"} <= set(ch), "required channels missing"
    # radiance and the fit statistics are float32; the whole-number channels (valid, count,
    # flags) half floats, which hold them exactly
    for name, v in ch.items():
        want = np.float16 if name in ("valid", "count", "flags") else np.float32
        assert v.dtype == want, f"channel {name} is {v.dtype.name}, expected {np.dtype(want).name}"
        if want == np.float16:
            assert np.all(np.mod(v, 1) == 0), f"channel {name} holds non-integers"
    exposures = [float(x) for x in str(header["exposures_s"]).split()]
    assert len(exposures) == header["exposure_count"]
    valid = ch["valid"] > 0.5
    truth = tch["radiance"]
    rel = np.abs(ch["radiance"][valid] - truth[valid]) / truth[valid]
    print(f"valid pixels {valid.sum()}, exposures {exposures[0]:g}..{exposures[-1]:g} s, "
          f"median relative error {100 * np.median(rel):.3f}%, "
          f"truth range {truth[valid].min():.3g}..{truth[valid].max():.3g} DN/s")


if __name__ == "__main__":
    main()
