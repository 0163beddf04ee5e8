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
# The CLI the round trips compare against, in the test profile that `cargo test` just built.
cargo build -q --profile test -p gantry
export GANTRY_BIN="$PWD/target/debug/gantry"
# The package as users get it (release profile; maturin's `--profile test` would hand Python a
# test-harness executable instead of the extension library).
VIRTUAL_ENV="$VENV" PATH="$VENV/bin:$PATH" "$VENV/bin/maturin" develop -q --release \
  -m bindings/python/Cargo.toml
# Dr.Jit's LLVM backend: the LLVM that .ci/setup.d/python.apt installs (LLVM 15 cannot compile
# Dr.Jit 1.5's kernels)
for lib in /usr/lib/x86_64-linux-gnu/libLLVM-19.so /usr/lib/x86_64-linux-gnu/libLLVM.so.19.1; do
  if [ -z "${DRJIT_LIBLLVM_PATH:-}" ] && [ -e "$lib" ]; then export DRJIT_LIBLLVM_PATH="$lib"; fi
done
"$PY" -m pytest -q bindings/python/tests
