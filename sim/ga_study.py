"""Ghoniem et al.'s Table 2, measured: GA alone, A* alone and GA+A*, time and path length.

``python -m sim.ga_study`` prints one table; ``--json FILE`` writes its rows.

Maps. The paper's map is one indoor room from a stereo camera, projected to a binary grid;
it gives no size, no obstacle layout and no cell size, only Table 2's lengths (5.61-6.82 m)
and a drawing (its Fig. 8). So two kinds of map are measured:

- ``room-N``: an N x N room (10 cm cells: 3, 6 and 10 m across, the 6 m one near the
  paper's path length), walls around it, furniture as random boxes of 2 to N/6 cells a side
  until ``density`` of it is covered; start near the bottom-left corner, goal near the
  top-right; a map that cuts them apart is drawn again. Seeded: ``--maps`` maps per setup.
- ``courtyard-N-U``: guidebelt's courtyard (``sim/courtyard.py``) with its unknown obstacles
  all known (the true map), inflated by the user's radius as the navigator does, from the
  scenario's start to its goal: the benchmark's world, planned once.

Methods, on the same map and ends (``cpu/genetic.py`` says how each is read from the paper):

- **GA**: the GA alone (straight feasible segments between waypoints, Euclidean Eq. 4);
- **A***: guidebelt's A* (``AStarPlanner``, octile, optimal), one search start to goal;
- **GA+A***: Algorithms 1-2 (A* between consecutive waypoints as the fitness), with the
  study's ``GaParams`` and with the planner's defaults (the daemon's ``ga-astar``).

Time is wall time of one call on one core (median of ``--repeats`` calls, then the median
over maps); the GA's includes its flood fill and map copy. Length is the path's length on
the 8-connected grid (10 cm a straight step, 14.14 cm a diagonal: cost / 10 x cell), medians
over the maps where the method found a path; ``vs A*`` is the median of the per-map ratios.
"""

from __future__ import annotations

import argparse
import json
import time
from collections.abc import Callable
from dataclasses import asdict, dataclass
from pathlib import Path

import numpy as np

from daemon.planning.cpu.astar import AStarPlanner
from daemon.planning.cpu.genetic import GaParams, evolve, evolve_straight
from daemon.planning.grid import CELL_M, INF, OCCUPIED, Cell
from daemon.planning.inflation import dilate
from sim.courtyard import make_courtyard

PAPER = {"GA": (75.0, 6.82), "A*": (191.0, 5.78), "GA+A*": (3.0, 5.61)}
"""Table 2 of the paper: (computational time s, path length m)."""

STUDY_PARAMS = GaParams(population=20, generations=20, waypoints=3)
"""The paper gives no population, generations or rates: these are ours, larger than the
planner's defaults so that the GA has room to converge on a room-sized map."""


@dataclass
class Row:
    setup: str
    method: str
    maps: int
    found: int
    ms_median: float
    length_m_median: float
    vs_astar_median: float
    searches_median: float


def room_map(side: int, density: float, rng: np.random.Generator) -> tuple[np.ndarray, Cell, Cell]:
    """A walled room with random boxes, its start (bottom-left) and goal (top-right)."""
    start, goal = (side - 3, 2), (2, side - 3)
    while True:
        blocked = np.zeros((side, side), bool)
        blocked[[0, -1], :] = blocked[:, [0, -1]] = True
        inner = (side - 2) ** 2
        top = max(3, side // 6)
        while blocked[1:-1, 1:-1].sum() < density * inner:
            r, c = rng.integers(1, side - 1, 2)
            hh, ww = rng.integers(2, top + 1, 2)
            blocked[r : r + hh, c : c + ww] = True
            blocked[[0, -1], :] = blocked[:, [0, -1]] = True
        for r, c in (start, goal):
            blocked[r - 1 : r + 2, c - 1 : c + 2] = False
        check = AStarPlanner()
        check.plan(blocked, goal)
        if check.cost_at(start) < INF:
            return blocked, start, goal


def courtyard_map(grid: int, unknown: float, seed: int) -> tuple[np.ndarray, Cell, Cell]:
    sc = make_courtyard(grid, unknown, seed=seed)
    return dilate(sc.true == OCCUPIED, sc.radius_cells), sc.start, sc.goal


def _timed(call: Callable[[], int], repeats: int) -> tuple[float, int]:
    """(median ms, cost) of ``repeats`` calls of ``call`` (which returns the path's cost)."""
    ms, cost = [], int(INF)
    for _ in range(repeats):
        t0 = time.perf_counter()
        cost = call()
        ms.append((time.perf_counter() - t0) * 1e3)
    return float(np.median(ms)), cost


def measure_map(
    blocked: np.ndarray, start: Cell, goal: Cell, seed: int, repeats: int,
    params: GaParams = STUDY_PARAMS,
) -> dict[str, tuple[float, int, int]]:  # fmt: skip
    """method -> (median ms, cost, A* searches) on one map; ``params`` for GA and GA+A*."""
    astar = AStarPlanner()

    def astar_once() -> int:
        astar.plan(blocked, goal)  # a new map version: the next read searches again
        astar.path(start)
        return astar.cost_at(start)  # the path's cost, remembered: no second search

    out: dict[str, tuple[float, int, int]] = {}
    study = GaParams(**{**asdict(params), "seed": seed})
    default = GaParams(seed=seed)
    for name, params, run in (
        ("GA", study, evolve_straight),
        ("GA+A*", study, evolve),
        ("GA+A* (planner)", default, evolve),
    ):
        results = []

        def once(run=run, params=params, results=results) -> int:
            results.append(run(blocked, start, goal, params))
            return results[-1].cost

        ms, cost = _timed(once, repeats)
        out[name] = (ms, cost, results[-1].searches)
    ms, cost = _timed(astar_once, repeats)
    out["A*"] = (ms, cost, 1)
    return out


def summarise(setup: str, per_map: list[dict[str, tuple[float, int, int]]]) -> list[Row]:
    rows = []
    for method in ("GA", "A*", "GA+A*", "GA+A* (planner)"):
        found = [m for m in per_map if m[method][1] < INF]
        length = [m[method][1] / 10 * CELL_M for m in found]
        ratio = [m[method][1] / m["A*"][1] for m in found if m["A*"][1] > 0]
        rows.append(Row(
            setup, method, len(per_map), len(found),
            float(np.median([m[method][0] for m in per_map])),
            float(np.median(length)) if length else float("nan"),
            float(np.median(ratio)) if ratio else float("nan"),
            float(np.median([m[method][2] for m in per_map])),
        ))  # fmt: skip
    return rows


def study(
    rooms: list[int], densities: list[float], courtyards: list[int], unknowns: list[float],
    maps: int, repeats: int, seed: int, params: GaParams = STUDY_PARAMS,
) -> list[Row]:  # fmt: skip
    rows: list[Row] = []
    for side in rooms:
        for density in densities:
            rng = np.random.default_rng([seed, side, int(density * 100)])
            per_map = [measure_map(*room_map(side, density, rng), seed + i, repeats, params)
                       for i in range(maps)]  # fmt: skip
            rows += summarise(f"room-{side} {density:.0%}", per_map)
    for grid in courtyards:
        for unknown in unknowns:
            per_map = [measure_map(*courtyard_map(grid, unknown, seed + i), seed + i, repeats,
                                   params)
                       for i in range(maps)]  # fmt: skip
            rows += summarise(f"courtyard-{grid} {unknown:.0%}", per_map)
    return rows


def format_rows(rows: list[Row]) -> str:
    lines = [f"{'setup':<18} {'method':<16} {'found':>7} {'time ms':>9} {'length m':>9} "
             f"{'vs A*':>6} {'A* runs':>7}"]  # fmt: skip
    for r in rows:
        lines.append(
            f"{r.setup:<18} {r.method:<16} {r.found:>3}/{r.maps:<3} {r.ms_median:>9.3f} "
            f"{r.length_m_median:>9.2f} {r.vs_astar_median:>6.3f} {r.searches_median:>7.0f}"
        )
    lines.append("paper (Table 2, one indoor map): " + ", ".join(
        f"{k} {t:.0f} s {m:.2f} m" for k, (t, m) in PAPER.items()))  # fmt: skip
    return "\n".join(lines)


def _floats(text: str) -> list[float]:
    return [float(x) for x in text.split(",") if x.strip()]


def main(argv: list[str] | None = None) -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--rooms", default="30,60,100", help="room sides in cells")
    p.add_argument("--densities", default="0.1,0.2,0.3", help="box cover of the rooms")
    p.add_argument("--courtyards", default="100,200", help="courtyard grid sides")
    p.add_argument("--unknowns", default="0.2,0.4", help="courtyard unknown fractions")
    p.add_argument("--maps", type=int, default=7, help="seeded maps per setup")
    p.add_argument("--repeats", type=int, default=3, help="timed calls per map and method")
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--population", type=int, default=STUDY_PARAMS.population)
    p.add_argument("--generations", type=int, default=STUDY_PARAMS.generations)
    p.add_argument("--waypoints", type=int, default=STUDY_PARAMS.waypoints)
    p.add_argument("--json", type=Path, default=None, help="write the rows here")
    a = p.parse_args(argv)
    params = GaParams(population=a.population, generations=a.generations, waypoints=a.waypoints)
    rows = study([int(x) for x in _floats(a.rooms)], _floats(a.densities),
                 [int(x) for x in _floats(a.courtyards)], _floats(a.unknowns), a.maps,
                 a.repeats, a.seed, params)  # fmt: skip
    print(f"GA+A* study: {a.maps} maps per setup, seed {a.seed}, study GaParams {params}, "
          f"planner GaParams {GaParams()}")  # fmt: skip
    print(format_rows(rows))
    if a.json is not None:
        a.json.parent.mkdir(parents=True, exist_ok=True)
        a.json.write_text(json.dumps([asdict(r) for r in rows], indent=1) + "\n")


if __name__ == "__main__":
    main()
