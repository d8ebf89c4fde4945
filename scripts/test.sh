#!/usr/bin/env bash
# Runs every test: lints, native unit and integration tests, wasm tests under
# Node, the npm package, and the page in headless Chromium. Installs what is
# missing first (scripts/setup.sh). Real-data tests read ../shared/data and
# skip with a message when it is absent.
set -euo pipefail
cd "$(dirname "$0")/.."

# Each section's wall time is printed when it ends (CI's time limit is the
# sum; see docs/performance.md "CI's time").
section_name=""
section_start=$SECONDS
section() {
  if [ -n "$section_name" ]; then
    echo "== $section_name: $((SECONDS - section_start)) s"
  fi
  section_name=$1
  section_start=$SECONDS
  [ -n "$section_name" ] && echo "== $section_name"
  return 0
}

section "setup"
bash scripts/setup.sh

section "lint"
cargo fmt --all -- --check
cargo clippy --all-targets --quiet -- -D warnings
# Doc links that do not resolve (or name private items) fail here, not in a reader's browser.
RUSTDOCFLAGS="-D warnings" cargo doc --no-deps --lib --quiet

section "native tests"
# Examples are measurements, not tests: clippy --all-targets has checked
# that they build. (The library has no doc tests.)
cargo test --quiet --lib --bins --tests

if [ -f scripts/test-wasm.sh ]; then
  section "wasm tests (Node), package build"
  bash scripts/test-wasm.sh
fi

if [ -d tests/browser ]; then
  section "browser tests (headless Chromium)"
  node --test --test-concurrency=1 tests/browser/
fi
section ""
echo "== all tests passed in $SECONDS s"
