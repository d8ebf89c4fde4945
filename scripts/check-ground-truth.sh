#!/usr/bin/env bash
# Measures a sequence's ground truth against Open3D's registration of its
# own depth frames (scripts/ground_truth_consistency.py says what and why).
# Not part of the tests.
#
#   scripts/check-ground-truth.sh [7-Scenes folder]   (default: the shared kitchen; runs ours first)
#   scripts/check-ground-truth.sh --tum <TUM folder>  (the registration's own spread)
set -euo pipefail
cd "$(dirname "$0")/.."
source scripts/open3d-venv.sh
if [[ ${1:-} == --tum ]]; then
  exec "$venv/bin/python" scripts/ground_truth_consistency.py --tum "$2"
fi
folder=${1:-../shared/data/7scenes_redkitchen_even}
cargo build --release --quiet
trajectory=target/ground-truth-check-trajectory.txt
target/release/surfel-slam run "$folder" -q --trajectory "$trajectory"
"$venv/bin/python" scripts/ground_truth_consistency.py "$folder" "$trajectory"
