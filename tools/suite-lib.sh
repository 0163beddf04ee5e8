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

# The gantry CLI in the test profile (the one `cargo test` built): its path in GANTRY_BIN.
build_gantry() {
  cargo build -q --profile test -p gantry
  export GANTRY_BIN="$TARGET/debug/gantry"
}

# The Python package into the venv, built in the dev profile, which is optimised like the test
# profile and so reuses every crate `cargo test` compiled (maturin's `--profile test` would hand
# Python a test-harness executable instead of the extension library; users' wheels are release
# builds: `maturin build --release`).
install_package() {
  VIRTUAL_ENV="$VENV" PATH="$VENV/bin:$PATH" "$VENV/bin/maturin" develop -q \
    -m bindings/python/Cargo.toml
}
