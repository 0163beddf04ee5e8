#!/usr/bin/env bash
# The distributed run of the corpus store: a small synthetic store packed by `gantry corpus
# synth`, opened with zarr-python, its Gram blocks computed on a Dask LocalCluster of 2 worker
# processes (loopback) through reflectance.linalg.gram, compared with `gantry corpus pca`.
set -euo pipefail
cd "$(dirname "$0")/../.."
VENV="${VENV:-$PWD/.venv}"
PY="$VENV/bin/python"
if [ ! -x "$PY" ]; then
  echo "50-dask: no Python venv at $VENV: run .ci/setup" >&2
  exit 1
fi
if ! "$PY" -c "import dask.distributed, zarr, numpy, pytest" 2>/dev/null; then
  echo "50-dask: dask[distributed], zarr, numpy or pytest missing in $VENV: run .ci/setup" >&2
  exit 1
fi
if ! "$PY" -c "import reflectance.linalg" 2>/dev/null; then
  # the Python suite (30-python.sh) normally installed it; build it here when run alone
  if [ ! -x "$VENV/bin/maturin" ]; then
    echo "50-dask: neither the reflectance package nor maturin is in $VENV: run .ci/setup" >&2
    exit 1
  fi
  VIRTUAL_ENV="$VENV" PATH="$VENV/bin:$PATH" "$VENV/bin/maturin" develop -q --release \
    -m bindings/python/Cargo.toml
fi
cargo build -q --profile test -p gantry
export GANTRY_BIN="$PWD/target/debug/gantry"
exec "$PY" -m pytest -q tools/dask/test_dask_gram.py
