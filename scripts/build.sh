#!/usr/bin/env bash
# Builds the WebAssembly modules and assembles the npm package.
#
#   scripts/build.sh              both modules -> pkg/ (+ pkg/threads/) and www/pkg/
#   scripts/build.sh --no-threads only the single-threaded SIMD module
#
# 1. single-threaded SIMD module: stable, +simd128 (from .cargo/config.toml),
#    target/wasm32-unknown-unknown/release/surfel_slam.wasm
# 2. threaded module: nightly, build-std, atomics + shared memory (flags from
#    ../shared/TOOLCHAIN.md; an env RUSTFLAGS replaces config.toml's, so
#    +simd128 is repeated), CARGO_TARGET_DIR=target-mt, feature `threads`
# 3. wasm-bindgen --target web for each, into pkg/ and pkg/threads/
# 4. pkg/ gets pkg-config/ (package.json with Cargo.toml's version, README,
#    LICENSE); www/pkg/ gets the modules for the page
# 5. SIMD check (scripts/check-simd.sh) and module sizes
#
# Idempotent; cargo makes repeated runs fast. Needs wasm-bindgen equal to
# Cargo.lock's wasm-bindgen version (0.2.130), and for the threaded module the
# nightly toolchain with rust-src and the wasm32 target.
set -euo pipefail
cd "$(dirname "$0")/.."

threads=1
for arg in "$@"; do
  case "$arg" in
    --no-threads) threads=0 ;;
    -h|--help) sed -n '2,20p' "$0"; exit 0 ;;
    *) echo "build.sh: unknown argument $arg" >&2; exit 2 ;;
  esac
done

crate=surfel_slam
target=wasm32-unknown-unknown

# The CLI must match the wasm-bindgen crate exactly (the JS glue and the
# module's custom section are versioned together).
want=$(awk '/^name = "wasm-bindgen"$/ { getline; gsub(/version = |"/, ""); print; exit }' Cargo.lock)
have=$(wasm-bindgen --version 2>/dev/null | awk '{print $2}' || true)
if [[ -z "$have" ]]; then
  echo "build.sh: wasm-bindgen not found; cargo install wasm-bindgen-cli --version $want" >&2
  exit 1
fi
if [[ -n "$want" && "$have" != "$want" ]]; then
  echo "build.sh: wasm-bindgen CLI is $have but Cargo.lock has $want; cargo install wasm-bindgen-cli --version $want" >&2
  exit 1
fi

echo "== single-threaded SIMD module (stable)"
cargo build --release --target "$target" --no-default-features --lib
st_wasm="target/$target/release/$crate.wasm"

if [[ $threads == 1 ]]; then
  echo "== threaded module (nightly, build-std)"
  RUSTFLAGS='-C target-feature=+simd128,+atomics,+bulk-memory -C link-arg=--shared-memory -C link-arg=--max-memory=1073741824 -C link-arg=--import-memory -C link-arg=--export=__wasm_init_tls -C link-arg=--export=__tls_size -C link-arg=--export=__tls_align -C link-arg=--export=__tls_base' \
  CARGO_TARGET_DIR=target-mt \
    cargo +nightly build --release --target "$target" --no-default-features --features threads --lib \
      -Z build-std=panic_abort,std
  mt_wasm="target-mt/$target/release/$crate.wasm"
fi

echo "== wasm-bindgen"
rm -rf pkg
mkdir -p pkg
wasm-bindgen --target web --out-dir pkg "$st_wasm"
if [[ $threads == 1 ]]; then
  wasm-bindgen --target web --out-dir pkg/threads "$mt_wasm"
  # wasm-bindgen-rayon 1.3's thread helper starts each thread with the init
  # function's old positional form, and every thread logs "using deprecated
  # parameters for the initialization function": pass the object form.
  for helper in pkg/threads/snippets/wasm-bindgen-rayon-*/src/workerHelpers*.js; do
    if [[ -f $helper ]]; then
      sed -i 's/pkg\.default(data\.module, data\.memory)/pkg.default({ module_or_path: data.module, memory: data.memory })/' "$helper"
    fi
  done
fi

echo "== package"
cp pkg-config/README.md pkg-config/LICENSE pkg/
version=$(awk -F'"' '/^version = / { print $2; exit }' Cargo.toml)
node -e '
  const fs = require("fs");
  const [src, dst, version, threads] = process.argv.slice(1);
  const pkg = JSON.parse(fs.readFileSync(src, "utf8"));
  pkg.version = version;
  if (threads !== "1") {
    delete pkg.exports["./threads"];
    delete pkg.exports["./threads/surfel_slam_bg.wasm"];
    pkg.files = pkg.files.filter((f) => !f.startsWith("threads"));
  }
  fs.writeFileSync(dst, JSON.stringify(pkg, null, 2) + "\n");
' pkg-config/package.json pkg/package.json "$version" "$threads"

echo "== www/pkg (for the page)"
rm -rf www/pkg
mkdir -p www/pkg
cp pkg/$crate.js pkg/${crate}_bg.wasm pkg/$crate.d.ts www/pkg/
if [[ $threads == 1 ]]; then
  cp -r pkg/threads www/pkg/threads
fi

echo "== SIMD check"
scripts/check-simd.sh pkg/${crate}_bg.wasm
if [[ $threads == 1 ]]; then
  scripts/check-simd.sh pkg/threads/${crate}_bg.wasm
fi

echo "== sizes"
for f in pkg/${crate}_bg.wasm pkg/threads/${crate}_bg.wasm; do
  if [[ -f $f ]]; then
    bytes=$(stat -c %s "$f")
    gz=$(gzip -9 -c "$f" | wc -c)
    printf '%-34s %8d bytes (%d KiB, gzip -9 %d KiB)\n' "$f" "$bytes" $((bytes / 1024)) $((gz / 1024))
  fi
done
echo "built pkg/ (surfel-slam $version) and www/pkg/"
