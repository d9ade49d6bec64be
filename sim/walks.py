"""Walks that follow the belt: sensor → inflation → planner → Guidance → belt walker.

The paper's courtyard walk, but the user is the ``BeltWalker``: it feels the pattern and steps
in continuous space with noise; it never sees the path. Each loop is one walker action
(``STEP_S`` of simulated time): the sensor reveals what it sees from the walker's cell and
heading, the planner repairs its field (EDS), the path is read from the walker's cell, Guidance
makes the pattern and the cue, the walker reacts.

Measured per walk: arrived or not, walked metres against the optimal path on the fully known
map (8-connected, the planner's own metric), collisions, cues spoken, holds.

Guidance lives in ``daemon.guidance`` (pydantic models), imported inside the functions so this
module still imports with numpy and numba only.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from daemon.planning import make_planner
from daemon.planning.dijkstra import dijkstra_field
from daemon.planning.escape import escape_path
from daemon.planning.grid import INF, Cell, cell_to_xy, in_bounds, xy_to_cell
from daemon.planning.inflation import InflatedMap

from .belt_walker import BeltWalker, WalkerParams
from .courtyard import Scenario, dilate, make_courtyard
from .sensor import Sensor

ESCAPE_REACH = 12
"""Cells searched for a way out of the inflation margin."""
STEP_S = 0.6
"""Simulated seconds per walker action (one step or one turn on the spot)."""


@dataclass(frozen=True)
class BeltWalk:
    arrived: bool
    reason: str
    walked_m: float
    optimal_m: float
    collisions: int
    cues: int
    holds: int
    actions: int
    track: np.ndarray
    """``(n, 2)`` walker positions in metres (x, y), start first."""

    @property
    def length_ratio(self) -> float:
        return self.walked_m / self.optimal_m if self.optimal_m > 0 else math.nan


def optimal_m(scenario: Scenario) -> float:
    """Length of the shortest 8-connected path on the fully known, inflated true map."""
    blocked = dilate(scenario.true == 1, scenario.radius_cells)
    g = int(dijkstra_field(blocked, scenario.goal)[scenario.start])
    return math.inf if g >= INF else g / 10.0 * scenario.cell_m


def belt_walk(
    scenario: Scenario,
    *,
    seed: int = 0,
    backend: str = "cpu",
    params: WalkerParams | None = None,
    smooth: bool = False,
    lang: str = "en",
    max_actions: int | None = None,
    guidance=None,
) -> BeltWalk:
    """One walk of ``scenario`` by a belt walker with noise seeded by ``seed``."""
    from daemon.guidance.guide import Guidance
    from protocol.messages import PatternKind, Pose

    planner = make_planner("eds", backend)
    guide = guidance if guidance is not None else Guidance(
        cell_m=scenario.cell_m, lang=lang, smooth=smooth
    )
    sensor = Sensor(scenario.sensor_range_cells)
    inflated = InflatedMap(scenario.known, scenario.radius_cells)
    planner.plan(inflated.blocked, scenario.goal)
    shape = scenario.shape
    x, y = cell_to_xy(shape, scenario.start, scenario.cell_m)
    walker = BeltWalker(
        x=x, y=y, heading=math.pi / 2, cell_m=scenario.cell_m,
        params=params or WalkerParams(), rng=np.random.default_rng(seed),
    )
    best = optimal_m(scenario)
    limit = max_actions or int(6 * best / walker.params.step_m) + 100
    now, cues, reason = 0.0, 0, "action limit"
    track = [(x, y)]
    for _ in range(limit):
        cell = xy_to_cell(shape, walker.x, walker.y, scenario.cell_m)
        if not in_bounds(shape, cell):
            reason = "left the map"
            break
        seen, values = sensor.sense(scenario.true, inflated.occupancy, cell, walker.heading)
        flipped, now_blocked = inflated.apply(seen, values)
        if flipped.size:
            planner.update(flipped, now_blocked)
        path = path_from(planner, inflated, cell)
        pose = Pose(x=walker.x, y=walker.y, heading=walker.heading, stamp=now)
        out = guide.guide(path, pose, shape, now, blocked=inflated.blocked)
        cues += out.cue is not None
        if out.pattern.kind is PatternKind.ARRIVED:
            reason = "arrived"
            break
        walker.react(out.pattern, scenario.true)
        track.append((walker.x, walker.y))
        now += STEP_S
    return BeltWalk(
        arrived=reason == "arrived",
        reason=reason,
        walked_m=walker.walked_m,
        optimal_m=best,
        collisions=walker.collisions,
        cues=cues,
        holds=guide.hold.holds,
        actions=len(track) - 1,
        track=np.array(track, dtype=np.float64),
    )


def path_from(planner, inflated: InflatedMap, cell: Cell) -> np.ndarray:
    """The path from the walker's cell, led out of the inflation margin the way the daemon
    does it (``planning.escape``) when a newly seen obstacle inflated over the walker."""
    if not inflated.blocked[cell]:
        return planner.path(cell)
    return escape_path(planner, inflated.blocked, inflated.occupancy, cell, ESCAPE_REACH)[0]


def _one(task: tuple) -> tuple[int, float, bool, float, int, int, int]:
    grid, unknown, seed, backend, smooth, params = task
    w = belt_walk(make_courtyard(grid, unknown, seed=seed), seed=seed, backend=backend,
                  smooth=smooth, params=params)
    return grid, unknown, w.arrived, w.length_ratio, w.collisions, w.cues, w.holds


def summarise(grid: int, unknown: float, results: list[tuple]) -> dict:
    """One JSON row from the per-walk tuples of ``_one``."""
    arrived = [r for r in results if r[2]]
    ratios = np.array([r[3] for r in arrived])
    return {
        "grid": grid,
        "unknown": unknown,
        "runs": len(results),
        "success_rate": round(len(arrived) / len(results), 4),
        "length_ratio": round(float(ratios.mean()), 4) if ratios.size else None,
        "length_ratio_max": round(float(ratios.max()), 4) if ratios.size else None,
        "collisions": int(sum(r[4] for r in results)),
        "cues_per_walk": round(float(np.mean([r[5] for r in results])), 2),
        "holds": int(sum(r[6] for r in results)),
    }


def run_table(
    grids: list[int],
    unknowns: list[float],
    runs: int,
    *,
    backend: str = "cpu",
    smooth: bool = False,
    first_seed: int = 0,
    jobs: int = 1,
    params: WalkerParams | None = None,
    on_row=None,
) -> list[dict]:
    """``runs`` seeded walks (seed i: the courtyard and the walker's noise) per grid and
    density; one row each. ``jobs`` > 1 spreads the walks over processes."""
    rows = []
    pool = None
    if jobs > 1:
        from concurrent.futures import ProcessPoolExecutor

        pool = ProcessPoolExecutor(jobs)
    try:
        for grid in grids:
            for unknown in unknowns:
                tasks = [
                    (grid, unknown, first_seed + i, backend, smooth, params) for i in range(runs)
                ]
                results = list(pool.map(_one, tasks) if pool else map(_one, tasks))
                rows.append(summarise(grid, unknown, results))
                if on_row is not None:
                    on_row(rows[-1])
    finally:
        if pool is not None:
            pool.shutdown()
    return rows
