"""Harmonic fields measured: the replanning step beside EDS on the same walk, and where the
paper's potential goes flat (grid size x float type).

``replan_rows``: the benchmark's walk (``walk.walk``, the daemon's navigator on the courtyard)
with ``harmonic`` and with ``eds`` on one backend; per row the median / p99 / max of the
replanning step (``step_ms``: the planner's repair + path read, wall clock, device
synchronisation included), sweeps per step and the first plan.

``plateau_rows``: the converged field of each map (log space, float64 on the CPU up to 400²,
the device's float32 above), then the same field stored as the paper's ``u`` and as ``1 − u``
in float32 and float64: a reachable cell with no strictly lower neighbour is a cell the
descent stops on. Storing the exact solution is the best any relaxation of that form can do
(a relaxation in that type also has to get there), so a plateau counted here is one the
paper's form cannot avoid. ``w`` itself is counted the same way.

Run: ``python -m sim.harmonic_bench replan --backend cuda --grid 400,2000 --json out.json``,
``python -m sim.harmonic_bench plateau --backend cuda --grid 100,400,2000 --json out.json``.
"""

from __future__ import annotations

import argparse
import json
import time

import numpy as np

from daemon.planning import make_planner
from daemon.planning.harmonic import relax as rx

from .courtyard import dilate
from .scenarios import make_scenario
from .walk import walk


def _pcts(values: np.ndarray) -> dict:
    if values.size == 0:
        return {"median": None, "p99": None, "max": None}
    return {"median": round(float(np.median(values)), 4),
            "p99": round(float(np.percentile(values, 99)), 4),
            "max": round(float(values.max()), 4)}  # fmt: skip


def replan_rows(grids: list[int], backend: str, max_steps: int | None, unknown: float = 0.4,
                planners: tuple[str, ...] = ("harmonic", "eds")) -> list[dict]:  # fmt: skip
    rows = []
    for grid in grids:
        scenario = make_scenario("courtyard", grid, unknown, 0)
        for name in planners:
            walk(scenario, backend=backend, mode=name, max_steps=3)  # compile and warm
            t0 = time.perf_counter()
            r = walk(scenario, backend=backend, mode=name, max_steps=max_steps)
            changed = r.changed > 0
            rows.append({
                "planner": name, "backend": backend, "grid": grid, "unknown": unknown,
                "arrived": r.arrived, "reason": r.reason, "steps": int(r.steps),
                "walked_m": round(r.walked_m, 2), "init_ms": round(float(r.init_ms), 2),
                "step_ms": _pcts(r.step_ms), "step_ms_changed": _pcts(r.step_ms[changed]),
                "sweeps": _pcts(r.iterations.astype(float)),
                "wall_s": round(time.perf_counter() - t0, 1),
            })  # fmt: skip
    return rows


def _stuck(values: np.ndarray, width: int, reach: np.ndarray, goal: int) -> int:
    return int(rx.stuck_cells(values, width, reach, goal))


def plateau_row(blocked: np.ndarray, goal: tuple[int, int], backend: str, label: str) -> dict:
    planner = make_planner("harmonic", backend)
    t0 = time.perf_counter()
    stats = planner.plan(blocked, goal)
    h, w = blocked.shape
    width = w + 2
    wfield = np.full((h + 2, width), rx.BLOCKED_W)
    wfield[1:-1, 1:-1] = planner.field()
    flat = wfield.reshape(-1)
    reach = np.where(planner.reach.reach, 1, -1).astype(np.int64)
    g = (goal[0] + 1) * width + goal[1] + 1
    finite = flat < rx.BLOCKED_W
    row = {"map": label, "grid": int(max(h, w)), "backend": backend,
           "cold_sweeps": stats.iterations, "cold_ms": round(stats.ms, 1),
           "reachable": int(planner.reach.count),
           "max_w": round(float(flat[finite].max()), 2),
           "plan_s": round(time.perf_counter() - t0, 2)}  # fmt: skip
    for dtype in (np.float32, np.float64):
        v = np.where(finite, np.exp(-np.minimum(flat, 800.0)), 0.0)
        # u stored: obstacles 1, the goal 0; 1 - u stored: obstacles 0, the goal 1 (negated so
        # that "lower" still means "towards the goal" for the count).
        u = np.where(finite, 1.0 - v, 1.0).astype(dtype)
        row[f"stuck_u_{dtype.__name__}"] = _stuck(u, width, reach, g)
        row[f"stuck_1mu_{dtype.__name__}"] = _stuck(-(v.astype(dtype)), width, reach, g)
        row[f"stuck_w_{dtype.__name__}"] = _stuck(flat.astype(dtype), width, reach, g)
    return row


def plateau_rows(grids: list[int], backend: str) -> list[dict]:
    rows = []
    for grid in grids:
        scenario = make_scenario("courtyard", grid, 0.4, 0)
        blocked = dilate(scenario.true == 1, scenario.radius_cells)
        rows.append(plateau_row(blocked, scenario.goal, backend, "courtyard"))
    return rows


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("what", choices=("replan", "plateau"))
    parser.add_argument("--backend", default="cpu")
    parser.add_argument("--grid", default="100,400")
    parser.add_argument("--max-steps", type=int, default=None)
    parser.add_argument("--json", default=None)
    a = parser.parse_args()
    grids = [int(x) for x in a.grid.split(",")]
    if a.what == "replan":
        rows = replan_rows(grids, a.backend, a.max_steps)
    else:
        rows = plateau_rows(grids, a.backend)
    text = json.dumps(rows, indent=1)
    print(text)
    if a.json:
        with open(a.json, "w") as f:
            f.write(text + "\n")


if __name__ == "__main__":
    main()
