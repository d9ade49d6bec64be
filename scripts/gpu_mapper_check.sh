#!/usr/bin/env bash
# The mapper's GPU machine check in one device call (run with the wheels carried: .whl):
#   1. pytest -m gpu tests/mapper: the CUDA kernel against the numba pass (cells, rays, map);
#   2. scripts/mapper_bench.py, RUNS times back to back (default 2): a 640x480 frame →
#      published delta, 300 frames, on cuda, as `guidebelt mapper` ships (the floor refitted
#      every 4th frame off the frame's path, taken by the next frame: FLOOR=next; "next path"
#      adds the fit on the path), the frames back to back and at a camera's 30 fps, the loop
#      sleeping as SLEEPS says (default whole: one sleep, as the CLI's --rate; also chunks,
#      spin, spin2: see the bench), the depth copied on the frame's path and lent (DEPTH,
#      default both: written by its producer into the pass's buffer); the first run also the pass's GPU vs host time (--split,
#      unless SPLIT=0);
#      the GPU's SM clock sampled every 100 ms meanwhile (clocks.csv), summed per row; a table
#      of the rows with the parts' p99 and how late the loop woke (the CPU's figures are the
#      dev VM's);
#   3. only if PARTS names it: the camera-in-the-loop table, 20 seeds, WALKS_PARALLEL at a
#      time (minutes; their outcome is what counts, not their timing).
# Usage, from the repository root: bash scripts/gpu_mapper_check.sh; output in $OUT_DIR
# (default out/gpu_mapper): device.txt, pytest.log, bench1.json.., split.json, clocks.csv,
# walks.jsonl.
set -uo pipefail
cd "$(dirname "$0")/.."
OUT_DIR=${OUT_DIR:-out/gpu_mapper}
PARTS=${PARTS:-tests bench}
FRAMES=${FRAMES:-300}
RUNS=${RUNS:-2}
SLEEPS=${SLEEPS:-whole}
FLOOR=${FLOOR:-next}
DEPTH=${DEPTH:-copied lent}
SPLIT=${SPLIT:-1}
WALKS_PARALLEL=${WALKS_PARALLEL:-10}
has() { [[ " $PARTS " == *" $1 "* ]]; }
mkdir -p "$OUT_DIR"
source scripts/device_env.sh
export PYTHONPATH="$PWD${PYTHONPATH:+:$PYTHONPATH}${CLI_SITE:+:$CLI_SITE}"
{ nvidia-smi --query-gpu=name,driver_version --format=csv,noheader; date -u +%FT%RZ;
  nproc; git describe --always --dirty 2>/dev/null || echo "commit unknown"; } \
    | tee "$OUT_DIR/device.txt"
if has tests; then
    timeout 200 python3 -m pytest -m gpu tests/mapper -q -p no:cacheprovider --tb=short 2>&1 \
        | tee "$OUT_DIR/pytest.log" | tail -n 40
fi
if has bench; then
    nvidia-smi --query-gpu=timestamp,clocks.sm,clocks.mem,pstate,utilization.gpu \
        --format=csv,noheader,nounits -lms 100 > "$OUT_DIR/clocks.csv" 2>/dev/null &
    clocks=$!
    for i in $(seq 1 "$RUNS"); do
        split=()
        [ "$i" -eq 1 ] && [ "$SPLIT" = 1 ] && split=(--split "$OUT_DIR/split.json")
        # shellcheck disable=SC2086  # SLEEPS, FLOOR and DEPTH are word lists
        timeout 240 python3 scripts/mapper_bench.py --backend cuda --floor-every 4 --fps 0 30 \
            --floor $FLOOR --sleep $SLEEPS --depth $DEPTH "${split[@]}" --frames "$FRAMES" \
            --cache /tmp/mapper_frames.pickle --json "$OUT_DIR/bench$i.json" >/dev/null
    done
    kill "$clocks" 2>/dev/null
    python3 - "$OUT_DIR/clocks.csv" "$OUT_DIR"/bench*.json <<'PY'
import json, sys, time
clocks = []  # (unix time, SM MHz): nvidia-smi stamps in local time, as time.mktime reads
for line in open(sys.argv[1]):
    try:
        ts, sm = (f.strip() for f in line.split(",")[:2])
        day, frac = ts.rsplit(".", 1)
        clocks.append((time.mktime(time.strptime(day, "%Y/%m/%d %H:%M:%S")) + float("0." + frac),
                       int(sm)))
    except ValueError:
        continue
print("| run | floor | depth | fps | sleep | median ms | p99 ms | max ms | p99 check / floor / bin / merge "
      "| woke late p99 ms | SM MHz min / median |")
print("|---|---|---|---|---|---|---|---|---|---|---|")
for i, name in enumerate(sys.argv[2:], 1):
    for r in json.load(open(name)):
        p, late = r["parts_p99_ms"], r.get("wake_late_ms") or {}
        sm = sorted(c for t, c in clocks if r["started_at"] <= t <= r["ended_at"])
        mhz = f"{sm[0]} / {sm[len(sm) // 2]}" if sm else "-"
        print(f"| {i} | {'next' if r['floor_async'] else 'path'} | {r.get('depth', 'copied')} | {r['fps']:g} | {r['sleep']} | "
              f"{r['median_ms']} | {r['p99_ms']} | {r['max_ms']} | {p['check']} / {p['floor']} / "
              f"{p['bin']} / {p['merge']} | {late.get('p99', '-')} | {mhz} |")
PY
    [ -f "$OUT_DIR/split.json" ] && cat "$OUT_DIR/split.json"
fi
if has walks; then
    rm -f "$OUT_DIR/walks.jsonl"
    # One short walk first: numba compiles (and caches) before the parallel walks start.
    timeout 300 python3 -c "from sim.camera_walk import camera_walk; camera_walk(0, max_steps=2)" \
        >/dev/null 2>&1
    seq 0 19 | xargs -P "$WALKS_PARALLEL" -I{} sh -c \
        "timeout 420 python3 scripts/camera_walks.py --only {} 2>/dev/null | grep '^{' >> '$OUT_DIR/walks.jsonl'"
    python3 - "$OUT_DIR/walks.jsonl" <<'PY'
import json, sys
rows = sorted((json.loads(l) for l in open(sys.argv[1])), key=lambda r: r["seed"])
for r in rows:
    print(r)
print(f"{sum(r['arrived'] for r in rows)}/{len(rows)} arrived, "
      f"{sum(r['collisions'] for r in rows)} collisions, {sum(r['stops'] for r in rows)} STOPs")
PY
fi
