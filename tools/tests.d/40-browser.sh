#!/usr/bin/env bash
# End-to-end tests of `gantry serve` in headless Chromium (tests/browser): builds gantry, makes
# a small corpus/model/trait set (tests/browser/make-fixture.sh), starts the server on a free
# port, runs the Playwright tests (they print the slider→sphere latencies and the real-time
# view's frame times), stops the server.
set -euo pipefail
source "$(dirname "$0")/../suite-lib.sh"
command -v node >/dev/null || { echo "error: node not found: run .ci/setup" >&2; exit 1; }
[ -x /usr/bin/chromium ] || { echo "error: /usr/bin/chromium not found: run .ci/setup (it installs chromium)" >&2; exit 1; }
[ -d tests/browser/node_modules/playwright-core ] || { echo "error: playwright-core missing: run .ci/setup (npm ci in tests/browser)" >&2; exit 1; }
# The test-profile build `cargo test` made (optimised; the plots wait for their draws).
build_gantry
GANTRY="$GANTRY_BIN"
WORK="$(mktemp -d)"
SERVER_PID=""
cleanup() { if [ -n "$SERVER_PID" ]; then kill "$SERVER_PID" 2>/dev/null || true; wait "$SERVER_PID" 2>/dev/null || true; fi; rm -rf "$WORK"; }
trap cleanup EXIT
# Starts `gantry serve` on the fixture in $1 (its corpus only with a second argument "corpus")
# and sets URL and SERVER_PID.
start_server() {
  if [ "${2:-}" = corpus ]; then set -- --corpus "$1/corpus"
  else set -- --corpus "$1/corpus" --model "$1/model.bin" --traits "$1/traits.json"; fi
  "$GANTRY" serve "$@" --port 0 >"$WORK/server.out" 2>"$WORK/server.err" &
  SERVER_PID=$!
  URL=""
  for _ in $(seq 1 120); do
    URL="$(sed -n 's/^gantry serve: //p' "$WORK/server.out")"
    [ -n "$URL" ] && break
    kill -0 "$SERVER_PID" 2>/dev/null || { echo "error: gantry serve exited:" >&2; cat "$WORK/server.err" >&2; exit 1; }
    sleep 0.5
  done
  [ -n "$URL" ] || { echo "error: gantry serve did not start" >&2; exit 1; }
  echo "server: $URL"
}
stop_server() { kill "$SERVER_PID" 2>/dev/null || true; wait "$SERVER_PID" 2>/dev/null || true; SERVER_PID=""; }

bash tests/browser/make-fixture.sh "$WORK/fx" "$GANTRY"
start_server "$WORK/fx"
GANTRY_URL="$URL" node tests/browser/serve.test.mjs ${SCREENSHOTS:-}
stop_server
# Editing out of the box: the corpus alone, a model and trait sets built from the page and
# cached beside the corpus, then a second start that edits at once from the cache.
ls -l "$WORK/fx/corpus" >"$WORK/corpus.before"
start_server "$WORK/fx" corpus
GANTRY_URL="$URL" node tests/browser/prepare.test.mjs ${SCREENSHOTS:-}
stop_server
[ -f "$(echo "$WORK"/fx/corpus.gantry-cache/*/complete)" ] || { echo "error: no complete cache entry beside the corpus" >&2; exit 1; }
start_server "$WORK/fx" corpus
PHASE=cached GANTRY_URL="$URL" node tests/browser/prepare.test.mjs ${SCREENSHOTS:-}
stop_server
ls -l "$WORK/fx/corpus" | cmp -s - "$WORK/corpus.before" || { echo "error: the corpus folder changed" >&2; exit 1; }
# The real-time WebGL2 view on software GL, on a model of 46 materials and 45 components:
# comparisons with the offline renderer, frame times, the slider latency.
bash tests/browser/make-fixture.sh "$WORK/fx46" "$GANTRY" 36
start_server "$WORK/fx46"
GANTRY_URL="$URL" node tests/browser/gpu.test.mjs ${SCREENSHOTS:-}
