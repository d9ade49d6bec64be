"""Run a planner's code paths once, before anyone waits on them.

numba compiles (or loads from its cache) each function on its first call, and a CUDA backend
compiles its kernels on first launch: 5–10 ms for a cached load, a second or more for a cold
compile. Without a warm-up the first user to reach a path pays it in one walking step
(measured: 5.7 ms in a 50² walk whose other steps took under 0.1 ms, the first path read
that settled a deferred repair). ``exercise`` runs a short seeded sequence of occupancy
changes through the inflation and the planner on a small map — walls across the route and
openings, path reads from cells the last repair deferred, the escape's window of costs — so
every entry point a walk uses has run once. The daemon calls it before it says READY
(``navigation/warm.py`` adds guidance), the benchmarks before they time anything.
"""

from __future__ import annotations

import numpy as np

from .escape import escape_path
from .grid import FREE, OCCUPIED, Cell, path_cost
from .inflation import InflatedMap
from .interface import GlobalPlanner

SIDE = 48
"""A small map: big enough for the deferred repairs of a focused planner, quick to plan."""
RADIUS = 2


def exercise(planner: GlobalPlanner, steps: int = 40, seed: int = 0) -> None:
    """Plan, then ``steps`` seeded occupancy changes, each followed by a replanning step and a
    path read from elsewhere, then the escape and a full settle. A planner made of ``parts``
    (one serves small maps, another large ones) has each part exercised."""
    parts = getattr(planner, "parts", None)
    if parts is not None:
        for part in parts():
            exercise(part, steps, seed)
        return
    rng = np.random.default_rng(seed)
    occupancy = np.full((SIDE, SIDE), FREE, dtype=np.uint8)
    occupancy[SIDE // 2, 6 : SIDE - 6] = OCCUPIED  # a wall with gaps at both ends: paths bend
    inflated = InflatedMap(occupancy, RADIUS)
    goal: Cell = (SIDE - 3, SIDE // 2)
    user: Cell = (2, SIDE // 2)
    planner.plan(inflated.blocked, goal)
    path = planner.path(user)
    # A block in a corner, far from the path: the step a device planner answers without a
    # repair (``deferred_blocks.py``, whose compiled check runs only then).
    flipped, now = inflated.apply(np.array([0], dtype=np.int64), np.array([OCCUPIED], np.uint8))
    user = (int(path[1][0]), int(path[1][1]))
    _stats, path = planner.update_and_path(flipped, now, user)
    for i in range(steps):
        # Runs of eight cells, closed twice and opened once in three: repairs of both signs.
        row = int(rng.integers(RADIUS + 1, SIDE - RADIUS - 1))
        col = int(rng.integers(0, SIDE - 8))
        cells = row * SIDE + np.arange(col, col + 8, dtype=np.int64)
        values = np.full(cells.size, OCCUPIED if i % 3 != 2 else FREE, dtype=np.uint8)
        flipped, now = inflated.apply(cells, values)
        if len(path) > 1:
            user = (int(path[1][0]), int(path[1][1]))  # the user walks the path
        if i % 4 == 3:
            # The changes alone, then a read: a step whose changes reach the planner before its
            # path is read (the route's escape, a pocket) calls ``update``, compiled on its own.
            planner.update(flipped, now)
            path = planner.path(user)
        else:
            _stats, path = planner.update_and_path(flipped, now, user)
        planner.cost_at(user)
        path_cost(path)  # the navigator reports the path's cost every step
        planner.path((int(rng.integers(0, SIDE)), int(rng.integers(0, SIDE))))
    # A user inside the margin: the escape reads a window of costs (``costs_within``).
    wall: Cell = (SIDE // 2, SIDE // 2)
    escape_path(planner, inflated.blocked, inflated.occupancy, wall, reach=2 * RADIUS + 2)
    settle = getattr(planner, "settle", None)
    if settle is not None:
        settle()
