#!/usr/bin/env bash
# The mapper's GPU machine check in one device call (run with the wheels carried: .whl):
#   1. pytest -m gpu tests/mapper (the CuPy pass against the numba one);
#   2. scripts/mapper_bench.py, cuda then cpu (the host's CPU, for reference): 640x480
#      frame → published delta, 300 frames;
#   3. the camera-in-the-loop table, 20 seeds, WALKS_PARALLEL at a time (the machine's
#      cores; the walks' timing is not what is measured, their outcome is).
# Usage, from the repository root: bash scripts/gpu_mapper_check.sh; output in $OUT_DIR
# (default out/gpu_mapper), the table's rows in walks.jsonl.
set -uo pipefail
cd "$(dirname "$0")/.."
OUT_DIR=${OUT_DIR:-out/gpu_mapper}
PARTS=${PARTS:-tests bench walks}
WALKS_PARALLEL=${WALKS_PARALLEL:-10}
has() { [[ " $PARTS " == *" $1 "* ]]; }
mkdir -p "$OUT_DIR"
source scripts/device_env.sh
export PYTHONPATH="$PWD${PYTHONPATH:+:$PYTHONPATH}${CLI_SITE:+:$CLI_SITE}"
{ nvidia-smi --query-gpu=name,driver_version --format=csv,noheader; date -u +%FT%RZ;
  git describe --always --dirty 2>/dev/null || echo "commit unknown"; } >"$OUT_DIR/device.txt"
has tests && timeout 200 python3 -m pytest -m gpu tests/mapper -q -p no:cacheprovider \
    --timeout 120 2>&1 | tail -n 5 | tee "$OUT_DIR/pytest.log"
if has bench; then
    timeout 200 python3 scripts/mapper_bench.py --backend cuda --frames 300 \
        --json "$OUT_DIR/bench_cuda.json" 2>&1 | tail -n 2
    timeout 200 python3 scripts/mapper_bench.py --backend cpu --frames 300 \
        --json "$OUT_DIR/bench_cpu.json" 2>&1 | tail -n 2
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
