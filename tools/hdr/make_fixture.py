#!/usr/bin/env python3
"""Writes crates/hdr/tests/fixtures/openexr_python.exr with the reference OpenEXR library
(pip install OpenEXR numpy), so that the Rust reader is tested against an independent writer.

Content: 4 x 3 pixels; radiance[i] = 0.5 * 3**i, valid = i % 2, count = i;
attributes exposures_s = "0.001 0.01 0.1", low_dn 10, high_dn 1000, min_correlation 0.998,
min_valid 3, intercept "fitted", position 5, angle_deg 42.5.
"""
import os

import numpy as np
import OpenEXR

here = os.path.dirname(os.path.abspath(__file__))
out = os.path.join(here, "..", "..", "crates", "hdr", "tests", "fixtures", "openexr_python.exr")
i = np.arange(12, dtype=np.float32).reshape(3, 4)
channels = {
    "radiance": (0.5 * 3.0 ** i).astype(np.float32),
    "valid": (i % 2).astype(np.float32),
    "count": i.astype(np.float32),
}
header = {
    "compression": OpenEXR.ZIP_COMPRESSION,
    "type": OpenEXR.scanlineimage,
    "hdr_kind": "radiance",
    "radiance_units": "DN/s",
    "exposures_s": "0.001 0.01 0.1",
    "low_dn": 10.0,
    "high_dn": 1000.0,
    "min_correlation": 0.998,
    "min_valid": 3,
    "intercept": "fitted",
    "position": 5,
    "angle_deg": 42.5,
}
with OpenEXR.File(header, channels) as f:
    f.write(out)
print("wrote", os.path.normpath(out), os.path.getsize(out), "bytes")
