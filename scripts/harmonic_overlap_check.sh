#!/usr/bin/env bash
# The harmonic planner's early relaxation (round 16's overlap) on the device, one call:
#   1. pytest -m gpu: the overlap's CUDA tests (the same field to the bit with and without it,
#      undo, the 400² bench walk both ways) and the warm-up's (the cuda walk loads nothing);
#   2. sim.harmonic_bench replan at $REPLAN_GRIDS ($BIG_STEPS steps), harmonic and EDS, with the
#      overlap, without it, and with it again (A/B/A on one machine, each a fresh process).
# Each replan's JSON is copied to $OUT's top level (files in its subfolders may not come back)
# and its log ends with one summary line a row (median / p99 / max, early starts, undone).
# Usage on the GPU machine, from the repository root: bash scripts/harmonic_overlap_check.sh
set -uo pipefail
cd "$(dirname "$0")/.."
OUT=${GPU_CHECK_OUT:-out/harmonic_overlap_check}
mkdir -p "$OUT"
source scripts/device_env.sh
export PYTHONPATH="$PWD${PYTHONPATH:+:$PYTHONPATH}${CLI_SITE:+:$CLI_SITE}"
{ nvidia-smi --query-gpu=name,driver_version --format=csv,noheader; date -u +%FT%RZ;
  git describe --always --dirty 2>/dev/null; } >"$OUT/device.txt"
fail=0
step pytest 200 python3 -m pytest -m gpu -q -p no:cacheprovider --timeout 120 --durations=5 \
    tests/daemon/planning/harmonic/test_harmonic_overlap_cuda.py \
    tests/daemon/planning/harmonic/test_harmonic_warm_cuda.py
bench() {
    step "$1" 150 python3 -m sim.harmonic_bench replan --backend cuda \
        --grid "${REPLAN_GRIDS:-400}" --max-steps "${BIG_STEPS:-60}" "${@:2}" \
        --json "$OUT/$1.json"
    grep -E '^harmonic ' "$OUT/$1.log"
}
bench overlap_1
bench ordered --no-overlap
bench overlap_2
exit "$fail"
