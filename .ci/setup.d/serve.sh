#!/usr/bin/env bash
# The browser tests of gantry serve: playwright-core from the committed lock file (it drives
# Debian's /usr/bin/chromium from serve.apt; no browser is downloaded).
set -euo pipefail
cd "$(dirname "$0")/../../tests/browser"
npm ci --no-audit --no-fund --silent
