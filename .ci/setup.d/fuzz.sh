#!/usr/bin/env bash
# The nightly toolchain and cargo-fuzz, for the sanitizer runs of the fuzz targets
# (fuzz/campaign.py, fuzz/run.sh, and the smoke of tools/tests.d/20-fuzz.sh when
# FUZZ_SMOKE_SECONDS is set). CI replays the committed fuzz inputs on stable instead, so they
# are installed only when asked: FUZZ_TOOLS=1 or FUZZ_SMOKE_SECONDS set.
set -euo pipefail
if [ -z "${FUZZ_TOOLS:-}" ] && [ -z "${FUZZ_SMOKE_SECONDS:-}" ]; then
  exit 0
fi
if ! cargo +nightly --version >/dev/null 2>&1; then
  rustup toolchain install nightly --profile minimal
fi
if ! cargo +nightly fuzz --version >/dev/null 2>&1; then
  cargo install --locked cargo-fuzz
fi
