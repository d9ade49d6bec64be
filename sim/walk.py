"""The paper's closed loop: sense → inflate → replan → step one cell → repeat until the goal.

Each step:
1. the sensor reveals what it sees from the user's cell and heading (a map delta);
2. ``InflatedMap.apply`` inflates the delta by the user's radius, giving the cells whose
   blocked state flipped (timed as ``inflate_ms``);
3. the planner repairs its field — ``update`` (EDS) or ``replan`` (DSS) — and the path
   is read from the user's cell, in one ``update_and_path`` call (one host round trip on
   the GPU); these two together are the paper's "replanning step" (``step_ms``, wall
   clock, includes any device synchronisation);
4. the user moves to the next cell of the path and faces half a metre ahead along it.

Both modes compute the same exact field and read the path with the same neighbour
order, so EDS and DSS walk the same cells; only their cost differs.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from daemon.planning import make_planner
from daemon.planning.grid import INF, NEIGHBOUR_COST, NEIGHBOUR_DC, NEIGHBOUR_DR, Cell, in_bounds
from daemon.planning.inflation import InflatedMap
from daemon.planning.interface import GlobalPlanner

from .courtyard import Scenario
from .sensor import Sensor

MODES = ("eds", "dss")
LOOKAHEAD_M = 0.5
"""The user faces the path point this far ahead, so the field of view follows the path."""

StepCallback = Callable[[int, Cell, int, float], None]
"""``on_step(step, cell, cells_changed, step_ms)`` after each step."""


@dataclass
class WalkResult:
    """What one walk did, step by step (arrays have one entry per step)."""

    mode: str
    planner: str
    arrived: bool
    reason: str
    """``arrived``, ``no path`` (the goal cannot be reached from the user) or ``step limit``."""
    walked: np.ndarray
    """``(steps + 1, 2) int32``: the cells the user stood on, start first."""
    iterations: np.ndarray
    cells_touched: np.ndarray
    plan_ms: np.ndarray
    """The planner's own time for update/replan + path (``update_and_path``'s statistics)."""
    step_ms: np.ndarray
    """Wall clock around update/replan + path extraction: the replanning step."""
    inflate_ms: np.ndarray
    changed: np.ndarray
    """Cells whose blocked state flipped at this step."""
    init_ms: float
    """The first full plan on the known map, before the walk."""
    known: np.ndarray
    """The known occupancy at the end of the walk."""
    blocked: np.ndarray
    """The inflated known map at the end of the walk."""
    cell_m: float

    @property
    def steps(self) -> int:
        return len(self.walked) - 1

    @property
    def walked_m(self) -> float:
        if len(self.walked) < 2:
            return 0.0
        d = np.abs(np.diff(self.walked.astype(np.int64), axis=0)).sum(axis=1)
        return float(np.where(d == 2, math.sqrt(2.0), 1.0).sum() * self.cell_m)


def heading_along(path: np.ndarray, lookahead: int, fallback: float) -> float:
    """Bearing (0 = east, counter-clockwise) from ``path[0]`` to the point ``lookahead`` on."""
    if len(path) < 2:
        return fallback
    r0, c0 = path[0]
    r1, c1 = path[min(lookahead, len(path) - 1)]
    return math.atan2(-(int(r1) - int(r0)), int(c1) - int(c0))


def escape_step(planner: GlobalPlanner, cell: Cell) -> Cell | None:
    """The best neighbour when the user's own cell has just become blocked.

    A newly seen obstacle beside the user can inflate over the cell they stand on; they
    then step to the neighbour (fixed order on ties) with the least cost to the goal.
    """
    best, best_cost = None, int(INF)
    for dr, dc, cost in zip(NEIGHBOUR_DR, NEIGHBOUR_DC, NEIGHBOUR_COST, strict=True):
        n = (cell[0] + int(dr), cell[1] + int(dc))
        if in_bounds(planner.shape, n):
            g = planner.cost_at(n)
            if g < INF and g + int(cost) < best_cost:
                best, best_cost = n, g + int(cost)
    return best


def walk(
    scenario: Scenario,
    backend: str = "cpu",
    variant: str = "fast",
    mode: str = "eds",
    fov_deg: float = 80.0,
    max_steps: int | None = None,
    planner: GlobalPlanner | None = None,
    on_step: StepCallback | None = None,
) -> WalkResult:
    """Walk ``scenario`` from start to goal, replanning every step; ``planner`` overrides."""
    if mode not in MODES:
        raise ValueError(f"unknown mode {mode!r}; choose one of {MODES}")
    planner = planner if planner is not None else make_planner(mode, backend, variant)
    h, w = scenario.shape
    max_steps = max_steps if max_steps is not None else 10 * (h + w)
    sensor = Sensor(scenario.sensor_range_cells, fov_deg)
    lookahead = max(1, round(LOOKAHEAD_M / scenario.cell_m))

    inflated = InflatedMap(scenario.known, scenario.radius_cells)
    init_ms = planner.plan(inflated.blocked, scenario.goal).ms
    user, heading = scenario.start, math.pi / 2  # facing north, towards the goal side
    walked = [user]
    rec: dict[str, list[float]] = {k: [] for k in ("it", "touched", "plan", "step", "infl", "chg")}
    reason = "step limit"
    for step in range(1, max_steps + 1):
        if user == scenario.goal:
            reason = "arrived"
            break
        cells, values = sensor.sense(scenario.true, inflated.occupancy, user, heading)
        t0 = time.perf_counter()
        flipped, now = inflated.apply(cells, values)
        t1 = time.perf_counter()
        stats, path = planner.update_and_path(flipped, now, user)
        t2 = time.perf_counter()
        for key, value in (
            ("it", stats.iterations),
            ("touched", stats.cells_touched),
            ("plan", stats.ms),
            ("step", (t2 - t1) * 1e3),
            ("infl", (t1 - t0) * 1e3),
            ("chg", flipped.size),
        ):
            rec[key].append(value)
        if len(path) >= 2:
            nxt = (int(path[1][0]), int(path[1][1]))
            heading = heading_along(path, lookahead, heading)
        else:
            escape = escape_step(planner, user) if inflated.blocked[user] else None
            if escape is None:
                reason = "no path"
                break
            nxt = escape
        user = nxt
        walked.append(user)
        if on_step is not None:
            on_step(step, user, int(flipped.size), rec["step"][-1])
    else:
        if user == scenario.goal:
            reason = "arrived"
    return WalkResult(
        mode=mode,
        planner=getattr(planner, "name", type(planner).__name__),
        arrived=reason == "arrived",
        reason=reason,
        walked=np.array(walked, dtype=np.int32),
        iterations=np.array(rec["it"], dtype=np.int64),
        cells_touched=np.array(rec["touched"], dtype=np.int64),
        plan_ms=np.array(rec["plan"], dtype=np.float64),
        step_ms=np.array(rec["step"], dtype=np.float64),
        inflate_ms=np.array(rec["infl"], dtype=np.float64),
        changed=np.array(rec["chg"], dtype=np.int64),
        init_ms=init_ms,
        known=inflated.occupancy.copy(),
        blocked=inflated.blocked.copy(),
        cell_m=scenario.cell_m,
    )
