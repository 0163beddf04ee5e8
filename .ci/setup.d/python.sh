#!/usr/bin/env bash
# Python package (bindings/python) and its Mitsuba 3 plugin: build backend and test-time packages,
# pinned, into the virtual environment at $VENV.
set -euo pipefail
: "${VENV:?VENV must point at the virtual environment (.ci/setup exports it)}"
"$VENV/bin/python" -m pip install -q \
  "maturin==1.16.0" \
  "numpy==2.3.5" \
  "pytest==9.2.0" \
  "mitsuba==3.9.1" \
  "drjit==1.5.0"
