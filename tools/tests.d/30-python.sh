#!/usr/bin/env bash
# The Python package (bindings/python) and its Mitsuba 3 plugin: installs the package into $VENV
# (the extension library from the test-profile build, tools/suite-lib.sh), then runs its pytest
# suite (round trips against the gantry CLI, the plugin's furnace and sphere
# comparisons). Needs .ci/setup (numpy, pytest, mitsuba in $VENV; libllvm).
set -euo pipefail
source "$(dirname "$0")/../suite-lib.sh"
need_python 30-python numpy pytest mitsuba drjit
# The CLI the round trips compare against.
build_gantry
install_package
# Dr.Jit's LLVM backend: the LLVM that .ci/setup.d/python.apt installs (LLVM 15 cannot compile
# Dr.Jit 1.5's kernels)
for lib in /usr/lib/x86_64-linux-gnu/libLLVM-19.so /usr/lib/x86_64-linux-gnu/libLLVM.so.19.1; do
  if [ -z "${DRJIT_LIBLLVM_PATH:-}" ] && [ -e "$lib" ]; then export DRJIT_LIBLLVM_PATH="$lib"; fi
done
"$PY" -m pytest -q bindings/python/tests
