"""Time the cuda planner (fast, paper) and the CPU on recorded courtyard walks and on DSS plans.

A walk of ``sim.walk`` over ``sim.courtyard`` is recorded once per courtyard
with the CPU planner (every backend computes the same exact field, so every backend walks
the same cells): the map delta of each step and the user's cell. The recording is then
replayed on an EDS and a DSS planner of each kind: per step ``update``, then ``path`` from the
user's cell, timed on the wall clock as the paper's replanning step. Replaying keeps the
scenario's inflation (slow on the CPU at 1000 and 2000 cells a side) out of the run time,
gives every variant identical input, and at the end the device field is compared with the
CPU's bit for bit. ``--dss`` sizes time DSS (``update`` with no change: from scratch on the
map already on the device) + ``path`` on the whole inflated true map, and once ``plan`` with
the map's upload.

The ``--big`` grids (1000, 2000) use a lighter recording, because ``InflatedMap.apply`` takes
seconds per step there: the true map is dilated once and each step reveals the dilated truth
inside the sensor's view (3 m, 80°), for ``--big-steps`` steps along the path.

    python3 scripts/time_cuda_planner.py --variants fast,paper,cpu \\
        --grid 100,200,400 --unknown 0.2,0.4,0.6 --big 1000,2000 --big-steps 40 \\
        --dss 400,2000,4000 --json out.json
"""

from __future__ import annotations

import argparse
import functools
import json
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from daemon.planning import make_planner
from daemon.planning.grid import OCCUPIED
from daemon.planning.interface import GlobalPlanner
from sim.courtyard import dilate, make_courtyard
from sim.sensor import Sensor
from sim.walk import LOOKAHEAD_M, heading_along, walk


class Recorder(GlobalPlanner):
    """Passes calls to a planner and keeps each step's delta and path start."""

    def __init__(self, inner: GlobalPlanner) -> None:
        self.inner, self.steps, self.name = inner, [], "recorder"

    def plan(self, blocked, goal):
        self.initial = (np.array(blocked, copy=True), goal)
        return self.inner.plan(blocked, goal)

    def update(self, cells, blocked):
        self.steps.append([np.array(cells, copy=True), np.array(blocked, copy=True), None])
        return self.inner.update(cells, blocked)

    def path(self, start):
        if self.steps and self.steps[-1][2] is None:
            self.steps[-1][2] = start
        return self.inner.path(start)

    def cost_at(self, cell):
        return self.inner.cost_at(cell)

    goal = property(lambda self: self.inner.goal)
    shape = property(lambda self: self.inner.shape)


def make(spec: str, mode: str) -> GlobalPlanner:
    """``cpu`` (the CPU's fast form), ``fast`` or ``paper`` (cuda), as ``mode`` (eds, dss)."""
    if spec == "cpu":
        return make_planner(mode, "cpu", "fast")
    return make_planner(mode, "cuda", spec)


def replay(spec: str, rec: Recorder, mode: str, truth: np.ndarray) -> dict:
    planner = make(spec, mode)
    blocked, goal = rec.initial
    planner.plan(blocked, goal)
    repair = planner.update
    step_ms, repair_ms, iters = [], [], []
    for cells, values, start in rec.steps:
        t0 = time.perf_counter()
        st = repair(cells, values)
        t1 = time.perf_counter()
        if start is not None:
            planner.path(start)
        t2 = time.perf_counter()
        step_ms.append((t2 - t0) * 1e3)
        repair_ms.append((t1 - t0) * 1e3)
        iters.append(st.iterations)
    # The same steps through update_and_path: repair, path and read-back with one sync.
    fused, fused_ms = make(spec, mode), []
    fused.plan(blocked, goal)
    for cells, values, start in rec.steps:
        t0 = time.perf_counter()
        if start is None:
            fused.update(cells, values)
        else:
            fused.update_and_path(cells, values, start)
        fused_ms.append((time.perf_counter() - t0) * 1e3)
    return {
        "variant": spec, "mode": mode, "steps": len(step_ms),
        "step_ms_median": float(np.median(step_ms)),
        "step_ms_p90": float(np.percentile(step_ms, 90)),
        "repair_ms_median": float(np.median(repair_ms)),
        "path_ms_median": float(np.median(np.subtract(step_ms, repair_ms))),
        "iter_median": float(np.median(iters)),
        "fused_ms_median": float(np.median(fused_ms)),
        "fused_ms_p90": float(np.percentile(fused_ms, 90)),
        "exact": bool(np.array_equal(planner.costs(), truth))
        and bool(np.array_equal(fused.costs(), truth)),
    }  # fmt: skip


def record(grid: int, unknown: float, max_steps: int | None) -> tuple[Recorder, np.ndarray]:
    rec = Recorder(make_planner("eds", "cpu", "fast"))
    walk(make_courtyard(grid, unknown, seed=0), mode="eds", planner=rec, max_steps=max_steps)
    return rec, rec.inner.costs()


def record_light(grid: int, unknown: float, steps: int) -> tuple[Recorder, np.ndarray]:
    sc = make_courtyard(grid, unknown, seed=0)
    truth = dilate(sc.true == OCCUPIED, sc.radius_cells).reshape(-1)
    known = dilate(sc.known == OCCUPIED, sc.radius_cells)
    rec = Recorder(make_planner("eds", "cpu", "fast"))
    rec.plan(known, sc.goal)
    known = known.reshape(-1)
    sensor = Sensor(sc.sensor_range_cells, 80.0)
    lookahead = max(1, round(LOOKAHEAD_M / sc.cell_m))
    user, heading = sc.start, np.pi / 2
    for _ in range(steps):
        seen = sensor.visible(sc.shape, user, heading)
        diff = np.unique(seen[known[seen] != truth[seen]])
        known[diff] = truth[diff]
        rec.update(diff, truth[diff])
        path = rec.path(user)
        if len(path) < 2:
            break
        heading = heading_along(path, lookahead, heading)
        user = (int(path[1][0]), int(path[1][1]))
    return rec, rec.inner.costs()


@functools.cache
def dss_case(size: int) -> tuple:
    """The courtyard, its inflated true map and the CPU's plan on it (built once per size)."""
    sc = make_courtyard(size, 0.4, seed=0)
    blocked = dilate(sc.true == OCCUPIED, sc.radius_cells)  # == InflatedMap(...).blocked, faster
    cpu = make_planner("dss", "cpu", "fast")
    cpu.plan(blocked, sc.goal)
    return sc, blocked, cpu


def time_dss(spec: str, size: int, repeats: int) -> dict:
    sc, blocked, cpu = dss_case(size)
    planner = make(spec, "dss")
    t0 = time.perf_counter()
    planner.plan(blocked, sc.goal)  # includes sending the whole map to the device
    first_ms = (time.perf_counter() - t0) * 1e3
    times, plan_ms = [], []
    none = np.empty(0, np.int64)
    for _ in range(repeats):  # DSS from scratch on the map already there, then the path
        t0 = time.perf_counter()
        st = planner.update(none, np.empty(0, bool))
        path = planner.path(sc.start)
        times.append((time.perf_counter() - t0) * 1e3)
        plan_ms.append(st.ms)
    fused_ms = []
    for _ in range(repeats):  # the same through update_and_path (one synchronisation)
        t0 = time.perf_counter()
        _, fused_path = planner.update_and_path(none, np.empty(0, bool), sc.start)
        fused_ms.append((time.perf_counter() - t0) * 1e3)
    return {
        "variant": spec, "grid": size, "unknown": 0.4, "mode": "dss-only", "steps": repeats,
        "step_ms_median": float(np.median(times)), "repair_ms_median": float(np.median(plan_ms)),
        "iter_median": float(st.iterations), "path_len": len(path), "plan_with_upload_ms": first_ms,
        "fused_ms_median": float(np.median(fused_ms)),
        "exact": bool(np.array_equal(planner.costs(), cpu.costs()))
        and bool(np.array_equal(path, cpu.path(sc.start)))
        and bool(np.array_equal(fused_path, path)),
        "device_MB": planner.device_bytes() / 1e6 if hasattr(planner, "device_bytes") else 0.0,
    }  # fmt: skip


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--variants", default="fast,cpu")
    ap.add_argument("--grid", default="100,200,400")
    ap.add_argument("--unknown", default="0.4")
    ap.add_argument("--big", default="", help="grids recorded at 40 %% only, steps capped")
    ap.add_argument("--big-steps", type=int, default=40)
    ap.add_argument("--paper-max", type=int, default=400, help="largest grid for paper")
    ap.add_argument("--dss", default="")
    ap.add_argument("--repeats", type=int, default=10)
    ap.add_argument("--json", type=Path)
    args = ap.parse_args()
    ints = lambda s: [int(x) for x in s.split(",") if x]  # noqa: E731
    specs = args.variants.split(",")
    for spec in specs:  # compile (or load cached) kernels outside the timings
        warm = make(spec, "eds")
        warm.plan(np.zeros((40, 40), bool), (0, 0))
        warm.update(np.array([41]), np.array([True]))
        warm.path((39, 39))
    cases = [(g, float(u), None) for g in ints(args.grid) for u in args.unknown.split(",")]
    cases += [(g, 0.4, args.big_steps) for g in ints(args.big)]
    rows: list[dict] = []
    for grid, unknown, cap in cases:
        t0 = time.perf_counter()
        rec, truth = record(grid, unknown, cap) if cap is None else record_light(grid, unknown, cap)
        print(f"recorded {grid} x {unknown}: {len(rec.steps)} steps in "
              f"{time.perf_counter() - t0:.1f} s", flush=True)  # fmt: skip
        for spec in specs:
            if spec == "paper" and grid > args.paper_max:
                continue
            for mode in ("eds", "dss"):
                row = {"grid": grid, "unknown": unknown, **replay(spec, rec, mode, truth)}
                rows.append(row)
                print(json.dumps(row), flush=True)
    for size in ints(args.dss):
        for spec in specs:
            if spec == "paper" and size > args.paper_max:
                continue
            row = time_dss(spec, size, args.repeats if spec != "cpu" else 3)
            rows.append(row)
            print(json.dumps(row), flush=True)
    if args.json:
        args.json.write_text(json.dumps(rows, indent=1))
    print(f"\n{'variant':9} {'grid':>5} {'unk':>4} {'mode':8} {'steps':>5} {'step ms':>8} "
          f"{'repair':>8} {'path':>7} {'p90':>7} {'fused':>7} {'iter':>6} exact")  # fmt: skip
    for r in rows:
        print(f"{r['variant']:9} {r['grid']:5} {r['unknown']:4} {r['mode']:8} {r['steps']:5} "
              f"{r['step_ms_median']:8.3f} {r['repair_ms_median']:8.3f} "
              f"{r.get('path_ms_median', 0):7.3f} {r.get('step_ms_p90', 0):7.3f} "
              f"{r.get('fused_ms_median', 0):7.3f} "
              f"{r['iter_median']:6.0f} {r['exact']}")  # fmt: skip


if __name__ == "__main__":
    main()
