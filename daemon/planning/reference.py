"""A planner that recomputes the reference Dijkstra on every call.

Slow and obviously right: the yardstick for tests and for code that needs a planner
before a fast one is chosen. ``update`` is not incremental here; it exists so the
reference satisfies the same interface as every backend.
"""

from __future__ import annotations

import time

import numpy as np

from .dijkstra import dijkstra_field
from .grid import INF, Cell, in_bounds
from .interface import Planner, UpdateStats, reference_path


class ReferencePlanner(Planner):
    name = "reference"

    def __init__(self) -> None:
        self._blocked = np.zeros((1, 1), dtype=bool)
        self._goal: Cell = (0, 0)
        self._g = np.zeros((1, 1), dtype=np.int32)

    def _recompute(self) -> UpdateStats:
        t0 = time.perf_counter()
        self._g = dijkstra_field(self._blocked, self._goal)
        ms = (time.perf_counter() - t0) * 1e3
        reached = int(np.count_nonzero(self._g < INF))
        return UpdateStats(iterations=1, cells_touched=reached, ms=ms)

    def plan(self, blocked: np.ndarray, goal: Cell) -> UpdateStats:
        self._blocked = np.array(blocked, dtype=bool, copy=True)
        self._goal = (int(goal[0]), int(goal[1]))
        return self._recompute()

    def update(self, cells: np.ndarray, blocked: np.ndarray) -> UpdateStats:
        self._blocked.reshape(-1)[np.asarray(cells, dtype=np.int64)] = blocked
        return self._recompute()

    replan = update

    def costs(self) -> np.ndarray:
        return self._g.copy()

    def blocked(self) -> np.ndarray:
        return self._blocked.copy()

    def cost_at(self, cell: Cell) -> int:
        return int(self._g[cell]) if in_bounds(self.shape, cell) else int(INF)

    def path(self, start: Cell) -> np.ndarray:
        return reference_path(self._g, self._blocked, start)

    @property
    def goal(self) -> Cell:
        return self._goal

    @property
    def shape(self) -> tuple[int, int]:
        return (int(self._blocked.shape[0]), int(self._blocked.shape[1]))
