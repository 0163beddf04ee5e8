#!/usr/bin/env bash
# Runs every fuzz target (cargo-fuzz, libFuzzer, nightly toolchain) for SECONDS each (default 30,
# the CI smoke), starting from the committed seeds (fuzz/seeds/TARGET) plus the repository's
# own sample files of that format; new inputs go to fuzz/corpus/TARGET (not committed), crashes
# to fuzz/artifacts/TARGET. Fails on the first target that crashes, hangs (> 1 s per input) or
# allocates more than 2 GB.
#
#   fuzz/run.sh 30                    # smoke, every target
#   fuzz/run.sh 3600 frames npy       # long run of some targets
#   FUZZ_RUNS=10000000 fuzz/run.sh 7200 npy   # stop after 10 M executions (or the time)
set -euo pipefail
cd "$(dirname "$0")"
secs="${1:-30}"; shift || true
if ! cargo +nightly --version >/dev/null 2>&1; then
  echo "error: the nightly toolchain is missing (rustup toolchain install nightly); run .ci/setup" >&2
  exit 1
fi
if ! cargo +nightly fuzz --version >/dev/null 2>&1; then
  echo "error: cargo-fuzz is missing (cargo install --locked cargo-fuzz); run .ci/setup" >&2
  exit 1
fi
repo_seeds() {
  case "$1" in
    rig_toml) echo ../docs/rig.example.toml ;;
    scene_toml) echo ../crates/render/examples/scenes/rust_teapot.toml ;;
    exr) echo ../crates/hdr/tests/fixtures/openexr_python.exr ;;
    npy) ls ../crates/brdf/data/merl/*.npy | head -4 | paste -sd, ;;
    *) ;;
  esac
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
  rc=0
  nice -n 19 cargo +nightly fuzz run "$t" "corpus/$t" "seeds/$t" -- \
    -max_total_time="$secs" -rss_limit_mb=2048 -malloc_limit_mb=2048 -timeout=1 \
    -print_final_stats=1 "${extra[@]}" >"$log" 2>&1 || rc=$?
  grep -E "^#[0-9]+[[:space:]]+DONE|^stat::number_of_executed_units" "$log" || true
  if [ "$rc" -ne 0 ]; then
    grep -E "ERROR|SUMMARY|panicked|Test unit written" "$log" >&2 || tail -20 "$log" >&2
    echo "error: fuzz target $t failed (input in fuzz/artifacts/$t, log $PWD/$log)" >&2
    exit 1
  fi
done
