#!/usr/bin/env bash
# The GPU machine's whole check in one device call:
#   1. pytest -m gpu over tests/daemon/planning (the cuda cases of the property tests against
#      the reference Dijkstra, and the cuda planner's own tests), with the slowest listed;
#   2. guidebelt bench --backend cuda: the paper's closed-loop walk through the daemon's
#      navigator, 100/200/400 x 20/40/60 %;
#   3. guidebelt bench --backend cuda at 1000 (whole walks) and 2000 (the first $BIG_STEPS
#      steps: sensing and inflating a 3 m sweep of 5 mm cells on the host dominates there;
#      rows say "capped"), 40 %;
#   4. scripts/time_dss.py: DSS from scratch + path at 400, 2000, 4000 (fast and the paper's
#      form where it fits), exactness checked against the CPU, the planner's memory;
#   5. the short table (scripts/gpu_table.py), last.
# CPU figures are measured on the development machine, not here.
# Usage, from the repository root on the GPU machine: bash scripts/gpu_check.sh
# Logs and JSON go to $GPU_CHECK_OUT (default out/gpu_check). Exit status 1 if any step failed;
# the last line names each step's exit status (124: it ran past its limit). PARTS (default
# "tests bench dss"; also "scenarios": every scenario at 400 and 1000, and "harmonic": issue 21's
# scripts/harmonic_check.sh into $OUT/harmonic; "defer": the four 400² walks with EDS's
# DeferredBlocks on (as shipped), off and on again (registry.DEFER_BLOCKS_ON_DEVICE), then on
# and off at 1000², on at 2000²; "users": issue 28's scripts/gpu_users_check.sh
# without its tests, which "tests" runs, into $OUT/users; "mapper": scripts/gpu_mapper_check.sh's
# tests and bench into $OUT/mapper) picks steps.
set -uo pipefail
cd "$(dirname "$0")/.."
OUT=${GPU_CHECK_OUT:-out/gpu_check}
BIG_STEPS=${BIG_STEPS:-500}
PARTS=${PARTS:-tests bench dss}
has() { [[ " $PARTS " == *" $1 "* ]]; }
mkdir -p "$OUT"
rm -f "$OUT/steps.txt"
source scripts/device_env.sh
export PYTHONPATH="$PWD${PYTHONPATH:+:$PYTHONPATH}${CLI_SITE:+:$CLI_SITE}"
fail=0
{
    nvidia-smi --query-gpu=name,driver_version --format=csv,noheader
    date -u +%Y-%m-%dT%H:%MZ
    git describe --always --dirty 2>/dev/null || echo "commit unknown"  # a copied checkout may be stale: dirty says so
} >"$OUT/device.txt"
has tests && step pytest 420 python3 -m pytest -m gpu tests/daemon/planning -q \
    -p no:cacheprovider --timeout 120 --durations=8
has bench && {
step bench_cuda 150 python3 -m cli.app bench --grid 100,200,400 --unknown 0.2,0.4,0.6 \
    --backend cuda --json "$OUT/bench_cuda.json"
step bench_big_cuda 150 python3 -m cli.app bench --grid 1000 --unknown 0.4 \
    --backend cuda --json "$OUT/bench_big_cuda.json"
step bench_2000_cuda 150 python3 -m cli.app bench --grid 2000 --unknown 0.4 \
    --backend cuda --max-steps "$BIG_STEPS" --json "$OUT/bench_2000_cuda.json"
}
has scenarios && step bench_scen_cuda 240 python3 -m cli.app bench --grid 400,1000 \
    --unknown 0.4 --scenario courtyard,explore,building,streets --backend cuda \
    --json "$OUT/bench_scen_cuda.json"
# The bench with DeferredBlocks on or off (the first argument), the rest as sim.benchmark's.
DEFER_BENCH='import sys
from daemon.planning import registry
registry.DEFER_BLOCKS_ON_DEVICE = sys.argv.pop(1) == "on"
from sim.benchmark import main
main(sys.argv[1:])'
FOUR="courtyard,explore,building,streets"
has defer && {
for f in on off on2; do
    step "defer_400_$f" 200 python3 -c "$DEFER_BENCH" "${f%2}" --grid 400 --unknown 0.4 \
        --scenario "$FOUR" --backend cuda --json "$OUT/defer_400_$f.json"
done
for f in on off; do
    step "defer_1000_$f" 240 python3 -c "$DEFER_BENCH" "$f" --grid 1000 --unknown 0.4 \
        --scenario "$FOUR" --backend cuda --json "$OUT/defer_1000_$f.json"
done
step defer_2000_on 150 python3 -c "$DEFER_BENCH" on --grid 2000 --unknown 0.4 \
    --backend cuda --max-steps "$BIG_STEPS" --json "$OUT/defer_2000_on.json"
}
has harmonic && step harmonic 420 env GPU_CHECK_OUT="$OUT/harmonic" bash scripts/harmonic_check.sh
has users && step users 420 env GPU_CHECK_OUT="$OUT/users" PARTS="${USERS_PARTS:-walk cuda rate}" \
    bash scripts/gpu_users_check.sh
has mapper && step mapper 300 env OUT_DIR="$OUT/mapper" PARTS="tests bench" \
    bash scripts/gpu_mapper_check.sh
has dss && step dss 70 python3 scripts/time_dss.py --variants fast,paper \
    --sizes 400,2000,4000 --paper-max 400 --json "$OUT/dss.json"
has tests && sed -n '/slowest/,$p' "$OUT/pytest.log" | tail -n 14
python3 scripts/gpu_table.py "$OUT"
echo "steps: $(tr '\n' ' ' <"$OUT/steps.txt")"
exit "$fail"
