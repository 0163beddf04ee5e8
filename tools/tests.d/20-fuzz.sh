#!/usr/bin/env bash
# Fuzzing in CI: every committed fuzz input (seeds and the campaigns' minimized corpora) is
# replayed on stable by the end-to-end test `fuzz_replay` (part of `cargo test --workspace`).
# The sanitizer smoke run of every cargo-fuzz target needs the nightly toolchain and a long
# first build (about 35 min on 2 cores), so it runs when FUZZ_SMOKE_SECONDS is set (at most 30
# per target), e.g. `FUZZ_SMOKE_SECONDS=5 tools/run-tests`; it then fails without nightly or
# cargo-fuzz (`FUZZ_TOOLS=1 .ci/setup` installs both). Long runs: fuzz/campaign.py, fuzz/run.sh
# (docs/reliability.md).
set -euo pipefail
cd "$(dirname "$0")/../.."
if [ -z "${FUZZ_SMOKE_SECONDS:-}" ]; then
  echo "fuzz: committed inputs replayed on stable (fuzz_replay); sanitizer smoke not asked (FUZZ_SMOKE_SECONDS unset)"
  exit 0
fi
exec fuzz/run.sh "$FUZZ_SMOKE_SECONDS"
