#!/usr/bin/env bash
# Everything that tests the WebAssembly side, in order:
#   1. native reference poses for the parity check (tests/wasm_parity_native.rs
#      -> target/wasm-parity/*.bits, the poses' bits; see tests/wasm_common/mod.rs)
#   2. cargo test --release --target wasm32-unknown-unknown under Node
#      (wasm-bindgen-test-runner; tests/wasm_node.rs compares with step 1 and,
#      with SURFEL_SLAM_REQUIRE_PARITY=1, fails on a missing/stale reference)
#   3. scripts/build.sh: both modules, pkg/, www/pkg/, SIMD instruction check
#   4. node --test tests/node/ against the built package
#
#   scripts/test-wasm.sh [--no-threads]   (--no-threads: skip the nightly threaded build)
#
# Needs: wasm32-unknown-unknown target, wasm-bindgen-cli (= Cargo.lock's
# wasm-bindgen, provides wasm-bindgen-test-runner), node >= 18, wabt; for the
# threaded module nightly with rust-src.
set -euo pipefail
cd "$(dirname "$0")/.."

build_args=()
for arg in "$@"; do
  case "$arg" in
    --no-threads) build_args+=(--no-threads) ;;
    *) echo "test-wasm.sh: unknown argument $arg" >&2; exit 2 ;;
  esac
done

for tool in wasm-bindgen wasm-bindgen-test-runner node wasm-objdump; do
  command -v "$tool" >/dev/null || { echo "test-wasm.sh: $tool not found" >&2; exit 1; }
done

echo "== 1. native reference for the wasm parity check"
cargo test --test wasm_parity_native

echo "== 2. wasm tests under Node"
# Only the targets with wasm tests: the library's own (simd128 against the
# scalar code) and tests/wasm_node.rs; the other test files are native only,
# and building each as an empty wasm test cost CI time. In release, as the
# module ships: step 3's single-threaded module is then already built (the
# features resolve alike, see Cargo.toml's wasm32 dependencies).
SURFEL_SLAM_REQUIRE_PARITY=1 cargo test --release --target wasm32-unknown-unknown --no-default-features \
  --lib --test wasm_node -- --nocapture

echo "== 3. build (modules, package, SIMD check)"
scripts/build.sh "${build_args[@]}"

echo "== 4. the package under Node"
node --test tests/node/

echo "test-wasm.sh: all wasm tests passed"
