#!/usr/bin/env bash
# Counts WebAssembly SIMD (simd128) instructions in a module and fails when
# there are none (i.e. +simd128 did not reach the build).
#
#   scripts/check-simd.sh [module.wasm]   (default: pkg/surfel_slam_bg.wasm)
#
# Needs wasm-objdump (Debian package `wabt`).
set -euo pipefail
cd "$(dirname "$0")/.."
module=${1:-pkg/surfel_slam_bg.wasm}
if [[ ! -f $module ]]; then
  echo "check-simd: $module not found (run scripts/build.sh)" >&2
  exit 1
fi
if ! command -v wasm-objdump >/dev/null; then
  echo "check-simd: wasm-objdump not found (apt-get install wabt)" >&2
  exit 1
fi
# Every simd128 opcode's mnemonic starts with one of these lane-type prefixes.
counts=$(wasm-objdump -d "$module" \
  | grep -oE '\b(v128|f32x4|f64x2|i8x16|i16x8|i32x4|i64x2)\.[a-z0-9_]+' \
  | sort | uniq -c | sort -rn)
total=$(awk '{ s += $1 } END { print s + 0 }' <<<"$counts")
f32x4=$(awk '$2 ~ /^f32x4\./ { s += $1 } END { print s + 0 }' <<<"$counts")
bytes=$(stat -c %s "$module")
echo "$module: $bytes bytes, $total SIMD instructions ($f32x4 f32x4); most frequent:"
head -8 <<<"$counts" | sed 's/^/    /'
if [[ $total -eq 0 ]]; then
  echo "check-simd: FAIL: no SIMD instruction in $module (is +simd128 in the rustflags?)" >&2
  exit 1
fi
