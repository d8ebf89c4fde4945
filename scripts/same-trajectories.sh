#!/usr/bin/env bash
# Whether two builds of the CLI give the same trajectories, byte for byte, on
# every shared sequence: a change meant to alter no result (or one that acts
# only where the shared data never goes, like the mask of a hand in view).
#
#   scripts/same-trajectories.sh OLD_BINARY NEW_BINARY [DATA_DIR]
#
# Runs teddy, ICL-NUIM kt0, the kitchen and the long office at strides 1, 3,
# 5 and 10, without colour at 1 and 5, at half resolution, and the long
# office with Kinect-v1 noise simulated (seeds 1 and 2). Prints `same` or
# `DIFF` per run; exits 1 when any differs. DATA_DIR: ../shared/data.
set -euo pipefail
old=${1:?usage: same-trajectories.sh OLD_BINARY NEW_BINARY [DATA_DIR]}
new=${2:?usage: same-trajectories.sh OLD_BINARY NEW_BINARY [DATA_DIR]}
data=${3:-"$(dirname "$0")/../../shared/data"}
out=$(mktemp -d)
trap 'rm -rf "$out"' EXIT
differ=0
check() {
  local name=$1; shift
  "$old" run "$@" -q --trajectory "$out/old.txt" > /dev/null 2>&1 || true
  "$new" run "$@" -q --trajectory "$out/new.txt" > /dev/null 2>&1 || true
  if [[ -s "$out/old.txt" ]] && cmp -s "$out/old.txt" "$out/new.txt"; then
    echo "same $name"
  else
    echo "DIFF $name"
    differ=1
  fi
  rm -f "$out/old.txt" "$out/new.txt"
}
for s in tum_fr3_teddy icl_office_kt0 7scenes_redkitchen_even icl_office_kt0_long; do
  for opts in "--stride 1" "--stride 3" "--stride 5" "--stride 10" \
              "--stride 1 --depth-only" "--stride 5 --depth-only" "--stride 1 --half"; do
    # shellcheck disable=SC2086 # the options are words
    check "$s $opts" "$data/$s" $opts
  done
done
for seed in 1 2; do
  check "icl_office_kt0_long kinect-v1 seed $seed" "$data/icl_office_kt0_long" \
    --simulate-noise kinect-v1 --noise-seed "$seed"
done
exit "$differ"
