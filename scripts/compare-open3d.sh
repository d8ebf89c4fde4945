#!/usr/bin/env bash
# Side-by-side speed comparison with Open3D 0.20 on this machine, in one run:
# our whole frame (`surfel-slam bench`: decode, preprocess, track, fuse,
# predict) against Open3D's RGB-D odometry alone (hybrid Jacobian, frame
# pairs, image loading excluded). Not part of the tests.
#
#   scripts/compare-open3d.sh [dataset dir ...]   (default: both ../shared/data sequences)
#
# Installs Open3D into target/open3d-venv on first use (pip, ~1 min) and
# libusb (apt), which Open3D's import needs.
set -euo pipefail
cd "$(dirname "$0")/.."

source scripts/open3d-venv.sh
cargo build --release --quiet

datasets=("$@")
if [[ ${#datasets[@]} -eq 0 ]]; then
  datasets=(../shared/data/icl_office_kt0 ../shared/data/tum_fr3_teddy)
fi
for d in "${datasets[@]}"; do
  ours=$(target/release/surfel-slam bench "$d" | awk '/^median_ms_per_frame:/ { print $2 }')
  theirs=$("$venv/bin/python" scripts/open3d_odometry.py "$d" | awk '/^median_ms_per_pair:/ { print $2 }')
  awk -v d="$d" -v a="$ours" -v b="$theirs" 'BEGIN {
    printf "%s: surfel-slam full frame %.1f ms, Open3D odometry alone %.1f ms, ratio %.1fx\n", d, a, b, b / a
  }'
done
