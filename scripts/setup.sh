#!/usr/bin/env bash
# Installs everything the build, the demo and the tests need; idempotent and
# quick when everything is already there. Works on a fresh machine of this
# project's kind (Debian, rustup stable + nightly, node 20, root).
set -euo pipefail
cd "$(dirname "$0")/.."

log() { printf '== setup: %s\n' "$*"; }

log "rust targets"
rustup target add wasm32-unknown-unknown >/dev/null
if ! rustup toolchain list | grep -q '^nightly'; then
  log "installing nightly toolchain (threaded wasm build needs -Z build-std)"
  rustup toolchain install nightly --profile minimal
fi
rustup component add rust-src --toolchain nightly >/dev/null
rustup target add wasm32-unknown-unknown --toolchain nightly >/dev/null
rustup component add rustfmt clippy >/dev/null 2>&1 || true

# wasm-bindgen-cli must equal the wasm-bindgen version pinned in Cargo.lock.
want=$(awk '/^name = "wasm-bindgen"$/ {getline; gsub(/"/, "", $3); print $3; exit}' Cargo.lock)
have=$(wasm-bindgen --version 2>/dev/null | awk '{print $2}' || true)
if [ "$want" != "$have" ]; then
  log "installing wasm-bindgen-cli $want (found: ${have:-none}); takes ~4 minutes"
  # Not --locked: its lockfile names a crate version the registry mirror lacks.
  cargo install wasm-bindgen-cli --version "=$want" --force
else
  log "wasm-bindgen-cli $have"
fi

need_apt=()
[ -x /usr/bin/chromium ] || need_apt+=(chromium)
command -v wasm-objdump >/dev/null || need_apt+=(wabt)
if [ ${#need_apt[@]} -gt 0 ]; then
  log "apt-get install ${need_apt[*]}"
  export DEBIAN_FRONTEND=noninteractive
  apt-get update -qq
  apt-get install -y -qq "${need_apt[@]}" >/dev/null
fi

if [ -f package-lock.json ]; then
  if [ ! -d node_modules/playwright-core ] || [ ! -d node_modules/gltf-validator ] \
    || [ ! -d node_modules/typescript ] || [ ! -d node_modules/@types/node ]; then
    log "npm ci"
    npm ci --no-audit --no-fund --loglevel=error
  fi
fi
log "done"
