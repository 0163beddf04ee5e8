# Sourced by the suites of tools/tests.d: the repository root, the cargo target directory, the
# virtual environment, and checks of what .ci/setup installs.
cd "$(dirname "${BASH_SOURCE[0]}")/.."
ROOT="$PWD"
TARGET="${CARGO_TARGET_DIR:-$ROOT/target}"
VENV="${VENV:-$ROOT/.venv}"
PY="$VENV/bin/python"

# need_python SUITE MODULE...: the venv exists and imports every MODULE, or the suite fails
# with what to run.
need_python() {
  local suite="$1"; shift
  if [ ! -x "$PY" ]; then
    echo "$suite: no Python virtual environment at $VENV: run .ci/setup" >&2
    exit 1
  fi
  local m
  for m in "$@"; do
    if ! "$PY" -c "import $m" 2>/dev/null; then
      echo "$suite: $VENV lacks the Python package '$m': run .ci/setup" >&2
      exit 1
    fi
  done
}

# Every workspace target the suites use, in the test profile and with the workspace's features
# (the selection `cargo test --workspace --all-features` builds, plus the Python extension
# library, which no test target links): after `cargo test` only pyo3 and the extension compile.
# The gantry CLI's path goes to GANTRY_BIN.
build_gantry() {
  cargo build -q --profile test --workspace --all-features --lib --bins --tests
  export GANTRY_BIN="$TARGET/debug/gantry"
}

# The Python package into the venv, installed editable: the extension library build_gantry made
# is copied beside the Python sources (bindings/python/python/reflectance/_native.abi3.so, the
# name maturin gives it) and a .pth file puts that directory on the venv's path. It is the
# same library maturin builds from the same crate and features (pyproject.toml), in the test
# profile instead of a release build (users' wheels: `pip install ./bindings/python`).
install_package() {
  build_gantry
  local src="$ROOT/bindings/python/python"
  local lib="$src/reflectance/_native.abi3.so"
  cp -f "$TARGET/debug/lib_native.so" "$lib.tmp"
  mv -f "$lib.tmp" "$lib"
  local site
  site="$("$PY" -c 'import sysconfig; print(sysconfig.get_paths()["purelib"])')"
  echo "$src" > "$site/reflectance.pth"
}
