#!/usr/bin/env bash
# Fuzz smoke: every cargo-fuzz target for FUZZ_SMOKE_SECONDS (default 5; at most 30) on the nightly
# toolchain. Without nightly or cargo-fuzz it fails (run .ci/setup, which installs both);
# the long runs are `fuzz/run.sh SECONDS [TARGET...]` (see docs/reliability.md).
set -euo pipefail
cd "$(dirname "$0")/../.."
exec fuzz/run.sh "${FUZZ_SMOKE_SECONDS:-5}"
