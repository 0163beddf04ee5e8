#!/usr/bin/env bash
# Runs every fuzz target (cargo-fuzz, libFuzzer, nightly toolchain) for SECONDS each (default 30,
# the smoke), starting from the committed seeds (fuzz/seeds/TARGET), the committed corpus of the
# last campaign (fuzz/corpus/TARGET) and the repository's own sample files of that format; new
# inputs are added to fuzz/corpus/TARGET (fuzz/campaign.py minimizes it before it is committed),
# crashes go to fuzz/artifacts/TARGET. Fails on the first target that crashes, hangs (> 1 s per input, or
# as fuzz/timeouts.txt says) or
# allocates more than 2 GB.
#
#   fuzz/run.sh 30                    # smoke, every target
#   fuzz/run.sh 3600 frames npy       # long run of some targets
#   FUZZ_RUNS=10000000 fuzz/run.sh 7200 npy   # stop after 10 M executions (or the time)
set -euo pipefail
cd "$(dirname "$0")"
secs="${1:-30}"; shift || true
if ! cargo +nightly --version >/dev/null 2>&1; then
  echo "error: the nightly toolchain is missing: FUZZ_TOOLS=1 .ci/setup (or rustup toolchain install nightly)" >&2
  exit 1
fi
if ! cargo +nightly fuzz --version >/dev/null 2>&1; then
  echo "error: cargo-fuzz is missing: FUZZ_TOOLS=1 .ci/setup (or cargo install --locked cargo-fuzz)" >&2
  exit 1
fi
# The repository's own files of a target's format (fuzz/repo-seeds.txt), comma-separated.
repo_seeds() {
  awk -v t="$1" '$1 == t { printf "%s%s", sep, "../" $2; sep = "," }' repo-seeds.txt
}
targets=("$@")
[ ${#targets[@]} -gt 0 ] || mapfile -t targets < <(cargo +nightly fuzz list)
cargo +nightly fuzz build >/dev/null
for t in "${targets[@]}"; do
  mkdir -p "corpus/$t" "seeds/$t"
  extra=()
  s="$(repo_seeds "$t")"
  [ -z "$s" ] || extra=("-seed_inputs=$s")
  [ -z "${FUZZ_RUNS:-}" ] || extra+=("-runs=$FUZZ_RUNS")
  echo "== fuzz $t (${secs} s)"
  log="corpus/$t.log"
  timeout="$(awk -v t="$t" '$1 == t { print $2 }' timeouts.txt)"
  timeout="${timeout:-1}"
  rc=0
  nice -n 19 cargo +nightly fuzz run "$t" "corpus/$t" "seeds/$t" -- \
    -max_total_time="$secs" -rss_limit_mb=2048 -malloc_limit_mb=2048 -timeout="$timeout" \
    -print_final_stats=1 "${extra[@]}" >"$log" 2>&1 || rc=$?
  grep -E "^#[0-9]+[[:space:]]+DONE|^stat::number_of_executed_units" "$log" || true
  if [ "$rc" -ne 0 ]; then
    grep -E "ERROR|SUMMARY|panicked|Test unit written" "$log" >&2 || tail -20 "$log" >&2
    echo "error: fuzz target $t failed (input in fuzz/artifacts/$t, log $PWD/$log)" >&2
    exit 1
  fi
done
