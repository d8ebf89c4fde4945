#!/usr/bin/env bash
# Runs every test: lints, native unit and integration tests, wasm tests under
# Node, the npm package, and the page in headless Chromium. Installs what is
# missing first (scripts/setup.sh). Real-data tests read ../shared/data and
# skip with a message when it is absent.
set -euo pipefail
cd "$(dirname "$0")/.."

bash scripts/setup.sh

echo "== lint"
cargo fmt --all -- --check
cargo clippy --all-targets --quiet -- -D warnings

echo "== native tests"
cargo test --quiet

if [ -f scripts/test-wasm.sh ]; then
  echo "== wasm tests (Node), package build"
  bash scripts/test-wasm.sh
fi

if [ -d tests/browser ]; then
  echo "== browser tests (headless Chromium)"
  node --test --test-concurrency=1 tests/browser/
fi
echo "== all tests passed"
