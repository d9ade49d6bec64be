"""A planner that recomputes the reference Dijkstra on every call.

Slow and obviously right: the yardstick for tests and for code that needs a planner
before a fast one is chosen. ``update`` recomputes whether built as EDS or DSS: the
reference answers the same calls as every backend, not in the same way.
"""

from __future__ import annotations

import time

import numpy as np

from .dijkstra import dijkstra_field, reference_path
from .field import FieldPlanner
from .grid import INF, Cell, in_bounds
from .interface import UpdateStats


class ReferencePlanner(FieldPlanner):
    backend, variant = "reference", "dijkstra"

    def __init__(self, dss: bool = False) -> None:
        super().__init__(dss)
        self._blocked = np.zeros((1, 1), dtype=bool)
        self._goal: Cell = (0, 0)
        self._g = np.zeros((1, 1), dtype=np.int32)

    def _dijkstra(self) -> UpdateStats:
        t0 = time.perf_counter()
        self._g = dijkstra_field(self._blocked, self._goal)
        ms = (time.perf_counter() - t0) * 1e3
        reached = int(np.count_nonzero(self._g < INF))
        return UpdateStats(iterations=1, cells_touched=reached, ms=ms)

    def plan(self, blocked: np.ndarray, goal: Cell) -> UpdateStats:
        self._blocked = np.array(blocked, dtype=bool, copy=True)
        self._goal = (int(goal[0]), int(goal[1]))
        return self._dijkstra()

    def _repair(self, cells: np.ndarray, blocked: np.ndarray) -> UpdateStats:
        self._blocked.reshape(-1)[np.asarray(cells, dtype=np.int64)] = blocked
        return self._dijkstra()

    _recompute = _repair

    def costs(self) -> np.ndarray:
        return self._g.copy()

    def blocked(self) -> np.ndarray:
        return self._blocked.copy()

    def cost_at(self, cell: Cell) -> int:
        return int(self._g[cell]) if in_bounds(self.shape, cell) else int(INF)

    def path(self, start: Cell) -> np.ndarray:
        return reference_path(self._g, self._blocked, start)

    @property
    def shape(self) -> tuple[int, int]:
        return (int(self._blocked.shape[0]), int(self._blocked.shape[1]))
