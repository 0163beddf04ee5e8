#!/usr/bin/env bash
# The Python package (bindings/python) and its Mitsuba 3 plugin: builds the package into $VENV with
# maturin, then runs its pytest suite (round trips against the gantry CLI, the plugin's furnace and
# sphere comparisons). Needs .ci/setup (maturin, numpy, pytest, mitsuba in $VENV; libllvm).
set -euo pipefail
cd "$(dirname "$0")/../.."
VENV="${VENV:-$PWD/.venv}"
PY="$VENV/bin/python"
if [ ! -x "$PY" ]; then
  echo "error: no Python virtual environment at $VENV: run .ci/setup" >&2
  exit 1
fi
for mod in maturin numpy pytest mitsuba drjit; do
  if ! "$PY" -c "import $mod" 2>/dev/null; then
    echo "error: $VENV lacks the Python package '$mod': run .ci/setup" >&2
    exit 1
  fi
done
# The test profile is the one `cargo test` just built: the CLI and the package reuse its artifacts.
cargo build -q --profile test -p gantry
export GANTRY_BIN="$PWD/target/debug/gantry"
VIRTUAL_ENV="$VENV" PATH="$VENV/bin:$PATH" "$VENV/bin/maturin" develop -q --profile test \
  -m bindings/python/Cargo.toml
"$PY" -m pytest -q bindings/python/tests
