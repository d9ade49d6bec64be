"""The camera-in-the-loop table: seeded walks through the daemon, arrivals and collisions.

Usage: PYTHONPATH=. python scripts/camera_walks.py [--seeds 20] [--unknown 0.2] [--json F]
Each walk is ``sim.camera_walk.camera_walk`` (world → RGB-D frames → mapper → daemon → belt
over zenoh on 127.0.0.1, three people walking, the belt walker feeling the patterns).
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

from sim.camera_walk import CAMERA_UNKNOWN, camera_walk


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--seeds", type=int, default=20)
    ap.add_argument("--unknown", type=float, default=CAMERA_UNKNOWN)
    ap.add_argument("--people", type=int, default=3)
    ap.add_argument("--json", type=Path)
    ap.add_argument("--only", type=str, help="Comma-separated seeds (a share of a parallel run).")
    args = ap.parse_args()
    rows = []
    seeds = [int(s) for s in args.only.split(",")] if args.only else range(args.seeds)
    for seed in seeds:
        w = camera_walk(seed, args.unknown, args.people)
        row = {
            "seed": seed, "arrived": w.arrived, "reason": w.reason, "steps": w.steps,
            "collisions": w.collisions, "stops": w.stops, "frames": w.frames,
            "refused": w.refused, "people": w.people, "walk_s": round(w.walk_s, 1),
            "actions": w.actions, "bumps": w.bumps,
            "mapper_ms_median": round(float(np.median(w.mapper_ms)), 2),
            "mapper_ms_p99": round(float(np.percentile(w.mapper_ms, 99)), 2),
        }  # fmt: skip
        rows.append(row)
        print(json.dumps(row), flush=True)
    arrived = sum(r["arrived"] for r in rows)
    collisions = sum(r["collisions"] for r in rows)
    print(f"{arrived}/{len(rows)} arrived, {collisions} collisions, "
          f"{sum(r['stops'] for r in rows)} STOP patterns")  # fmt: skip
    if args.json:
        args.json.write_text(json.dumps(rows, indent=1) + "\n")


if __name__ == "__main__":
    main()
