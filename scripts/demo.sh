#!/usr/bin/env bash
# The browser demo: installs what is missing, builds the wasm modules and
# serves www/ on localhost (cross-origin isolated, so the threaded module runs).
# The page plays the bundled TUM fr3/teddy clip on load; drop any TUM,
# ICL-NUIM or 7-Scenes folder on it to run your own.
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/setup.sh
bash scripts/build.sh
exec node www/serve.mjs "$@"
