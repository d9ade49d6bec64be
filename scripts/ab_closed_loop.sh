#!/usr/bin/env bash
# A/B of the closed-loop `guidebelt bench --backend cuda` between this checkout and an earlier
# commit, on the GPU machine: runs alternate (new, old, new, old, ...) so that a slow stretch of
# the host hits both alike, and each run's DSS and EDS medians are printed, then the medians
# of the runs. Separate runs of one commit differ by ~10 µs at 400² (BENCHMARKS.md), so one
# run each says little.
# Usage: bash scripts/ab_closed_loop.sh OLD_COMMIT [RUNS] [GRID] [UNKNOWN]
# The old tree is `git archive`d into /tmp/ab_old; typer and rich: scripts/device_env.sh.
set -uo pipefail
cd "$(dirname "$0")/.."
OLD=$1 RUNS=${2:-4} GRID=${3:-400} UNKNOWN=${4:-0.4}
OUT=${AB_OUT:-out/ab}
mkdir -p "$OUT"
rm -rf /tmp/ab_old && mkdir -p /tmp/ab_old && git archive "$OLD" | tar -x -C /tmp/ab_old || exit 1
source scripts/device_env.sh
new=$(git describe --always --dirty 2>/dev/null || echo new)
for i in $(seq 1 "$RUNS"); do
    for side in new old; do
        tree=$PWD
        [ "$side" = old ] && tree=/tmp/ab_old
        PYTHONPATH="$tree${CLI_SITE:+:$CLI_SITE}" timeout 120 python3 -m cli.app bench \
            --grid "$GRID" --unknown "$UNKNOWN" --backend cuda \
            --json "$OUT/$side.$i.json" >"$OUT/$side.$i.log" 2>&1 || echo "$side run $i failed"
    done
done
python3 - "$OUT" "$RUNS" "$new" "$OLD" <<'PY'
import json, statistics, sys
out, runs, names = sys.argv[1], int(sys.argv[2]), {"new": sys.argv[3], "old": sys.argv[4]}
med = {}
for side in ("new", "old"):
    for i in range(1, runs + 1):
        try:
            rows = json.load(open(f"{out}/{side}.{i}.json"))
        except OSError:
            continue
        for r in rows:
            med.setdefault((side, r["mode"]), []).append(r["ms_median"])
for mode in ("dss", "eds"):
    for side in ("new", "old"):
        v = med.get((side, mode), [])
        runs_ms = " ".join(f"{x:.3f}" for x in v)
        m = statistics.median(v) if v else float("nan")
        print(f"{mode.upper()} {side:3} {names[side]:>14}: runs {runs_ms}  median {m:.3f} ms")
PY
