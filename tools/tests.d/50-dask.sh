#!/usr/bin/env bash
# The distributed run of the corpus store: a small synthetic store packed by `gantry corpus
# synth`, opened with zarr-python, its Gram blocks computed on a Dask LocalCluster of 2 worker
# processes (loopback) through reflectance.linalg.gram, compared with `gantry corpus pca`.
set -euo pipefail
source "$(dirname "$0")/../suite-lib.sh"
need_python 50-dask dask.distributed zarr numpy pytest
if ! "$PY" -c "import reflectance.linalg" 2>/dev/null; then
  # the Python suite (30-python.sh) normally installed it; build it here when run alone
  install_package
fi
build_gantry
exec "$PY" -m pytest -q tools/dask/test_dask_gram.py
