#!/usr/bin/env bash
# Python packages of the Dask run of the corpus store (tools/dask, tools/tests.d/50-dask.sh):
# Dask distributed, zarr-python (Zarr v3) with crc32c (the store's chunk checksums), numpy, pytest. The `reflectance` package itself is
# built from bindings/python by its own setup part.
set -euo pipefail
: "${VENV:?VENV must be set (run .ci/setup)}"
"$VENV/bin/pip" install -q "dask[distributed]==2026.8.0" "distributed==2026.8.0" \
  "zarr==3.1.6" "numcodecs==0.16.6" "crc32c==2.9.post0" "numpy==2.3.5" "pytest==9.2.0"
