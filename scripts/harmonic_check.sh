#!/usr/bin/env bash
# The harmonic planner's device check (issue 21), one device call:
#   1. pytest -m gpu over tests/daemon/planning/harmonic (CuPy engine and band against numba);
#   2. sim.harmonic_bench plateau: courtyard fields at $PLATEAU_GRIDS, where u / 1-u / w go flat;
#   3. sim.harmonic_bench replan: the replanning step, harmonic beside EDS, at $REPLAN_GRIDS
#      ($BIG_STEPS steps), each of the step stops in $STEPS (default: the planner's own; N: stop
#      on a field without a pit after N sweeps, N/M: fill the pits' basins after M, not 20);
#   4. sim.harmonic_bench band: guidance's cost per call with the harmonic band on the GPU.
# Usage on the GPU machine, from the repository root: bash scripts/harmonic_check.sh
set -uo pipefail
cd "$(dirname "$0")/.."
OUT=${GPU_CHECK_OUT:-out/harmonic_check}
PARTS=${PARTS:-tests plateau replan band}
has() { [[ " $PARTS " == *" $1 "* ]]; }
mkdir -p "$OUT"
source scripts/device_env.sh
export PYTHONPATH="$PWD${PYTHONPATH:+:$PYTHONPATH}${CLI_SITE:+:$CLI_SITE}"
{ nvidia-smi --query-gpu=name,driver_version --format=csv,noheader; date -u +%FT%RZ;
  git describe --always --dirty 2>/dev/null; } >"$OUT/device.txt"
fail=0
run() { local name=$1 limit=$2; shift 2; echo "== $name"; timeout "$limit" "$@" >"$OUT/$name.log" 2>&1
        local rc=$?; [ "$rc" -eq 0 ] || fail=1; tail -n 25 "$OUT/$name.log"; echo "   rc=$rc"; }
has tests && run pytest 200 python3 -m pytest -m gpu tests/daemon/planning/harmonic -q \
    -p no:cacheprovider --timeout 120 --durations=5
has plateau && run plateau 150 python3 -m sim.harmonic_bench plateau --backend cuda \
    --grid "${PLATEAU_GRIDS:-100,400,1000,2000}" --json "$OUT/plateau.json"
has replan && run replan 300 python3 -m sim.harmonic_bench replan --backend cuda \
    --grid "${REPLAN_GRIDS:-400,2000}" --max-steps "${BIG_STEPS:-300}" --steps "${STEPS:-}" \
    --json "$OUT/replan.json"
has band && run band 120 python3 -m sim.harmonic_bench band --backend cuda \
    --grid "${BAND_GRIDS:-100,400}" --max-steps "${BIG_STEPS:-300}" --json "$OUT/band.json"
exit "$fail"
