"""Time DSS from scratch (the whole field) + the path on large maps, and the planner's memory.

A walk's step repairs the field; this times the other end: ``update`` with no change on a
``dss`` planner recomputes the whole field on the map already there, then the path is read
from the start, on the wall clock; ``update_and_path`` does the same in one call. The map is
the courtyard's whole inflated true map at 40 %. Each field is compared with the CPU's, cell
for cell, and each path with the CPU's.

    python3 scripts/time_dss.py --variants fast,paper --sizes 400,2000,4000 --paper-max 400 \\
        --json out/dss.json
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

import numpy as np

from daemon.planning import FieldPlanner, make_planner
from daemon.planning.grid import OCCUPIED
from sim.courtyard import dilate, make_courtyard

NO_CHANGE = (np.empty(0, np.int64), np.empty(0, bool))


def planner(spec: str) -> FieldPlanner:
    """``cpu`` (the CPU's fast form), or ``fast`` / ``paper`` on cuda; always DSS."""
    made = make_planner("dss", "cpu") if spec == "cpu" else make_planner("dss", "cuda", spec)
    assert isinstance(made, FieldPlanner)
    return made


def time_dss(spec: str, size: int, repeats: int, reference: FieldPlanner) -> dict:
    sc = make_courtyard(size, 0.4, seed=0)
    blocked = dilate(sc.true == OCCUPIED, sc.radius_cells)
    p = planner(spec)
    t0 = time.perf_counter()
    p.plan(blocked, sc.goal)  # includes sending the whole map to the device
    first_ms = (time.perf_counter() - t0) * 1e3
    split, fused, stats = [], [], None
    for _ in range(repeats):
        t0 = time.perf_counter()
        stats = p.update(*NO_CHANGE)
        path = p.path(sc.start)
        split.append((time.perf_counter() - t0) * 1e3)
    for _ in range(repeats):
        t0 = time.perf_counter()
        _, fused_path = p.update_and_path(*NO_CHANGE, sc.start)
        fused.append((time.perf_counter() - t0) * 1e3)
    reference.plan(blocked, sc.goal)
    exact = (np.array_equal(p.costs(), reference.costs())
             and np.array_equal(path, reference.path(sc.start))
             and np.array_equal(fused_path, path))  # fmt: skip
    return {
        "variant": spec, "grid": size, "unknown": 0.4, "repeats": repeats,
        "step_ms_median": float(np.median(split)), "step_ms_max": float(np.max(split)),
        "fused_ms_median": float(np.median(fused)), "fused_ms_max": float(np.max(fused)),
        "iterations": int(stats.iterations) if stats else 0, "path_len": len(path),
        "plan_with_upload_ms": first_ms, "exact": bool(exact),
        "device_MB": p.device_bytes() / 1e6 if hasattr(p, "device_bytes") else None,
    }  # fmt: skip


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--variants", default="fast,paper")
    ap.add_argument("--sizes", default="400,2000,4000")
    ap.add_argument("--paper-max", type=int, default=400, help="largest size for paper")
    ap.add_argument("--repeats", type=int, default=10)
    ap.add_argument("--json", type=Path)
    args = ap.parse_args()
    specs = [s for s in args.variants.split(",") if s]
    for spec in specs:  # compile (or load cached) kernels outside the timings
        warm = planner(spec)
        warm.plan(np.zeros((40, 40), bool), (0, 0))
        warm.update_and_path(*NO_CHANGE, (39, 39))
    reference = planner("cpu")
    rows = []
    for size in (int(s) for s in args.sizes.split(",") if s):
        for spec in specs:
            if spec == "paper" and size > args.paper_max:
                continue
            rows.append(time_dss(spec, size, args.repeats if spec != "cpu" else 3, reference))
            print(json.dumps(rows[-1]), flush=True)
    if args.json:
        args.json.parent.mkdir(parents=True, exist_ok=True)
        args.json.write_text(json.dumps(rows, indent=1))


if __name__ == "__main__":
    main()
