#!/usr/bin/env bash
# Issue 28's check in one device call: many users on one GPU.
#   1. pytest -m gpu over $TESTS (default tests/daemon/planning/cuda): the cuda planner's
#      tests, the shared loop's (test_users.py: planners stepping interleaved and in batches,
#      exact against Dijkstra);
#   2. guidebelt bench, one user's closed-loop walk (400², 40 %, EDS): the 1-user figure of
#      BENCHMARKS.md, to see it unchanged;
#   3. guidebelt bench --users $COUNTS --backend cuda (and cpu): round-robin replay of each
#      user's own recorded walk, per-user step latency;
#   4. the same on $BASE (a tree whose daemon/planning/cuda is the one before the shared
#      loop), when given: the "before" figures, on the same card in the same call;
#   5. guidebelt bench --users $RATE_USERS --rate 10: open loop, every user at 10 Hz, the
#      steps due together served as one batch;
#   6. the same with --threads: a thread per user, as the daemon steps them; the calls that
#      meet on the device combined into shared posts (cuda/combine.py);
#   7. the short table, last.
# Usage, from the repository root on the GPU machine: bash scripts/gpu_users_check.sh
# (PARTS, default "tests walk cuda cpu rate threads", picks steps 1, 2, 3, the cpu half of 3,
# 5 and 6)
# Logs and JSON go to $GPU_CHECK_OUT (default out/gpu_users). WALKS_FILE: recorded walks
# (written by the first bench that needs them, read by the rest).
set -uo pipefail
cd "$(dirname "$0")/.."
OUT=${GPU_CHECK_OUT:-out/gpu_users}
COUNTS=${COUNTS:-1,4,16}
RATE_USERS=${RATE_USERS:-1,16,1000}
TESTS=${TESTS:-tests/daemon/planning/cuda}
RATE_S=${RATE_S:-8}
BASE=${BASE:-}
PARTS=${PARTS:-tests walk cuda cpu rate threads}
has() { [[ " $PARTS " == *" $1 "* ]]; }
WALKS_FILE=${WALKS_FILE:-$OUT/walks.pkl}
mkdir -p "$OUT"
rm -f "$OUT/steps.txt"
source scripts/device_env.sh
export PYTHONPATH="$PWD${PYTHONPATH:+:$PYTHONPATH}${CLI_SITE:+:$CLI_SITE}"
fail=0
users() {  # users NAME SECONDS ARGS...: guidebelt bench --users at 400², 40 %
    local name=$1 limit=$2
    shift 2
    step "$name" "$limit" python3 -m cli.app bench --grid 400 --unknown 0.4 \
        --walks-file "$WALKS_FILE" --json "$OUT/$name.json" "$@"
}
{
    nvidia-smi --query-gpu=name,driver_version --format=csv,noheader
    date -u +%Y-%m-%dT%H:%MZ
    git describe --always --dirty 2>/dev/null || echo "commit unknown"
} >"$OUT/device.txt"
# shellcheck disable=SC2086  # TESTS: several paths
has tests && step pytest 420 python3 -m pytest -m gpu $TESTS -q -p no:cacheprovider \
    --timeout 180 --durations=5
has walk && step walk1 120 python3 -m cli.app bench --grid 400 --unknown 0.4 --planner eds \
    --backend cuda --json "$OUT/walk1.json"
has cuda && users users_cuda 240 --users "$COUNTS" --backend cuda
if [ -n "$BASE" ]; then
    OUT_ABS=$(realpath -m "$OUT") WALKS_ABS=$(realpath -m "$WALKS_FILE")
    (cd "$BASE" && PYTHONPATH="$PWD${CLI_SITE:+:$CLI_SITE}" timeout 240 python3 -m cli.app \
        bench --grid 400 --unknown 0.4 --walks-file "$WALKS_ABS" --users "$COUNTS" \
        --backend cuda --json "$OUT_ABS/users_base.json" >"$OUT_ABS/users_base.log" 2>&1)
    echo "users_base rc=$? " >>"$OUT/steps.txt"
    (cd "$BASE" && PYTHONPATH="$PWD${CLI_SITE:+:$CLI_SITE}" timeout 120 python3 -m cli.app \
        bench --grid 400 --unknown 0.4 --planner eds --backend cuda \
        --json "$OUT_ABS/walk1_base.json" >"$OUT_ABS/walk1_base.log" 2>&1)
    echo "walk1_base rc=$? " >>"$OUT/steps.txt"
    tail -n 3 "$OUT/users_base.log"
fi
has cpu && users users_cpu 120 --users "$COUNTS" --backend cpu
has rate && users users_rate 300 --users "$RATE_USERS" --rate 10 --seconds "$RATE_S" --backend cuda
has threads && users users_threads 300 --users "$RATE_USERS" --rate 10 --seconds "$RATE_S" \
    --backend cuda --threads
python3 - "$OUT" <<'EOF'
import json, pathlib, sys
out = pathlib.Path(sys.argv[1])
print(open(out / "device.txt").read().strip().replace("\n", " | "))
print(f"{'run':<14}{'backend':<8}{'mode':<13}{'users':>6}{'steps':>8}{'median':>8}{'p99':>8}"
      f"{'max':>8}{'steps/s':>9}{'MB/user':>8}")
for name in ("users_base", "users_cuda", "users_cpu", "users_rate", "users_threads"):
    f = out / f"{name}.json"
    for r in json.loads(f.read_text()) if f.exists() else []:
        print(f"{name:<14}{r['backend']:<8}{r['mode']:<13}{r['users']:>6}{r['steps']:>8}"
              f"{r['median']:>8.3f}{r['p99']:>8.3f}{r['max']:>8.3f}{r['steps_per_s']:>9.0f}"
              f"{r['device_bytes'] / 1e6:>8.2f}"
              + (f" own p99 {r['own']['p99']:.3f}, kept up: {r['kept_up']}" if "own" in r else "")
              + (f", batch mean {r['batch_mean']:.1f} max {r.get('batch_max', '-')}" if "batches" in r else ""))
for name in ("walk1_base", "walk1"):
    w = out / f"{name}.json"
    for r in json.loads(w.read_text()) if w.exists() else []:
        print(f"{name} closed loop, 1 user, {r['mode']}: steps {r['steps']} median "
              f"{r['ms_median']:.3f} p99 {r['ms_p99']:.3f} max {r['ms_max']:.3f}")
EOF
echo "steps: $(tr '\n' ' ' <"$OUT/steps.txt")"
exit "$fail"
