#!/usr/bin/env bash
# The GPU machine's whole check in one device call (BENCHMARKS.md, "Planning on the GPU"):
#   0. scripts/probe_sync_latency.py: what fences, atomics, barriers and PCIe reads cost here;
#   1. pytest -m gpu over tests/gpu and tests/planning (the cuda-fast and cuda-paper cases);
#   2. guidebelt bench --backend cuda, then --backend cpu: 100/200/400 x 20/40/60 % unknown;
#   3. guidebelt bench, cuda then cpu, 1000 and 2000 at 40 %, each walk capped at $BIG_STEPS
#      steps (the CPU's DSS at 2000 x 2000 takes ~50 ms a step; rows say "capped");
#   4. scripts/time_cuda_planner.py: variants at 400 on the recorded walk (a launch per call,
#      replayed as a CUDA graph, instead of the resident loop; two blocks per SM, so that each
#      of the 169 tiles has a block of its own; the relaxation in grid-wide rounds instead of
#      asynchronous, launches from Python instead of the CUDA graph, in-tile Jacobi sweeps instead of scans, the path by its own launch and one warp,
#      the paper's form, each also through update_and_path), and DSS-only at 400, 2000, 4000;
#   5. scripts/profile_fast_phases.py: where a step's time goes (host parts, launch phases);
#   6. the short table (scripts/gpu_table.py), then the phases.
# Usage, from the repository root on the GPU machine: bash scripts/gpu_check.sh
# Logs and JSON go to $GPU_CHECK_OUT (default out/gpu_check). Exit status 1 if any step failed;
# the last line names each step's exit status (124: it ran past its limit). The GPU tests take
# ~270 s on an H100 with warm caches (tests/gpu 242 s, tests/planning 20 s), more on a fresh one.
# PARTS (default "probe tests bench replay phases") picks steps, to split the check over two
# device calls when one would pass the 10-minute limit; scripts/gpu_table.py then reads both
# folders' files from one folder.
set -uo pipefail
cd "$(dirname "$0")/.."
OUT=${GPU_CHECK_OUT:-out/gpu_check}
BIG_STEPS=${BIG_STEPS:-300}
PARTS=${PARTS:-probe tests bench replay phases}
has() { [[ " $PARTS " == *" $1 "* ]]; }
mkdir -p "$OUT"
rm -f "$OUT/steps.txt"
source scripts/device_env.sh
export PYTHONPATH="$PWD${PYTHONPATH:+:$PYTHONPATH}${CLI_SITE:+:$CLI_SITE}"
fail=0
step() {  # step NAME SECONDS COMMAND...: run with a time limit, log to $OUT/NAME.log
    local name=$1 limit=$2
    shift 2
    echo "== $name: $*"
    timeout "$limit" "$@" >"$OUT/$name.log" 2>&1
    local rc=$?
    [ "$rc" -eq 0 ] || fail=1
    echo "$name rc=$rc" >>"$OUT/steps.txt"
    tail -n 2 "$OUT/$name.log"
    echo "   rc=$rc"
}
{
    nvidia-smi --query-gpu=name,driver_version --format=csv,noheader
    date -u +%Y-%m-%dT%H:%MZ
    git describe --always --dirty 2>/dev/null || echo "commit unknown"  # a copied checkout may be stale: dirty says so
} >"$OUT/device.txt"
has probe && step probe 60 python3 scripts/probe_sync_latency.py
has tests && step pytest 420 python3 -m pytest -m gpu tests/gpu tests/planning -q \
    -p no:cacheprovider --timeout 120
has bench && {
step bench_cuda 100 python3 -m cli.app bench --grid 100,200,400 --unknown 0.2,0.4,0.6 \
    --backend cuda --json "$OUT/bench_cuda.json"
step bench_cpu 100 python3 -m cli.app bench --grid 100,200,400 --unknown 0.2,0.4,0.6 \
    --backend cpu --json "$OUT/bench_cpu.json"
step bench_big_cuda 70 python3 -m cli.app bench --grid 1000,2000 --unknown 0.4 \
    --backend cuda --max-steps "$BIG_STEPS" --json "$OUT/bench_big_cuda.json"
step bench_big_cpu 100 python3 -m cli.app bench --grid 1000,2000 --unknown 0.4 \
    --backend cpu --max-steps "$BIG_STEPS" --json "$OUT/bench_big_cpu.json"
}
has replay && step replay 200 python3 scripts/time_cuda_planner.py --variants fast,fast:graph,fast:2:2,fast:rounds,fast:direct,fast:0:1,fast:walk,paper,cpu \
    --grid 400 --unknown 0.4 --dss 400,2000,4000 --json "$OUT/replay.json"
has phases && {
step phases 120 python3 scripts/profile_fast_phases.py --grid 400 --dss 400,2000
for gap in work sleep; do
    step "phases_gap_$gap" 60 python3 scripts/profile_fast_phases.py --grid 400 --gap "$gap" --walk-only
done
}
has tests && tail -n 3 "$OUT/pytest.log"
python3 scripts/gpu_table.py "$OUT"
has phases && cat "$OUT"/phases*.log
has probe && cat "$OUT/probe.log"
echo "steps: $(tr '\n' ' ' <"$OUT/steps.txt")"
exit "$fail"
