#!/usr/bin/env bash
# A quicker device call while working on the kernels: the GPU tests, then the replayed 400²
# walk and DSS-only plans for the variants given ($VARIANTS), then where a step's time goes
# (scripts/profile_fast_phases.py), last.
# Usage on the GPU machine: bash scripts/gpu_quick.sh  (full check: scripts/gpu_check.sh)
set -uo pipefail
cd "$(dirname "$0")/.."
export PYTHONUNBUFFERED=1 GUIDEBELT_CUDA_STRICT=1 PYTHONPATH="$PWD${PYTHONPATH:+:$PYTHONPATH}"
VARIANTS=${VARIANTS:-fast,fast:graph}
DSS=${DSS:-400,2000}
OUT=${GPU_CHECK_OUT:-out/gpu_quick}
mkdir -p "$OUT"
fail=0
timeout 420 python3 -m pytest -m gpu tests/gpu tests/planning -q -p no:cacheprovider \
    --timeout 120 -x >"$OUT/pytest.log" 2>&1 || fail=1
tail -n 25 "$OUT/pytest.log"
timeout 200 python3 scripts/time_cuda_planner.py --variants "$VARIANTS" --grid 400 --unknown 0.4 \
    --dss "$DSS" --json "$OUT/replay.json" >"$OUT/replay.log" 2>&1 || fail=1
tail -n 30 "$OUT/replay.log"
timeout 120 python3 scripts/profile_fast_phases.py --grid 400 --dss "$DSS" >"$OUT/phases.log" 2>&1 \
    || fail=1
cat "$OUT/phases.log"
exit "$fail"
