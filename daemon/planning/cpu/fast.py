"""The default CPU planner: the paper's field, touching only the cells that can change.

Choice and why
- **Dial's buckets, compiled with numba** (``dial.py``). Costs are the integers 10 and
  14, so a circular array of 15 buckets is an exact O(1) priority queue: Dijkstra without a
  heap. numba compiles the loops to machine code with no C extension to build, and
  ``cache=True`` compiles them once per machine.
- **DSS** is Dijkstra from the goal over the whole grid.
- **EDS** repairs the field from the changed cells only: (1) the cells whose cost must rise are
  invalidated (g = INF) — a cell is invalidated when *every* neighbour that supported its g is
  blocked or invalidated, decided in increasing old g: exactly the cells whose cost rises,
  not the whole predecessor subtree, which on a grid full of equal-cost ties is far larger
  (a 3 x 3 box below the goal on an open 200 x 200 grid: 141 cells rise, the subtree has 1366);
  (2) every invalidated or newly freed cell is re-seeded with the best cost its neighbours
  offer; (3) Dijkstra with the buckets from those seeds until the queue is empty. Work is
  proportional to the cells whose cost changes and their neighbours. When a change raises more
  than ``CUT_OVER`` of the map's cells (a wall across the route: everything behind it), the
  repair gives up and computes the field from scratch, which is then the cheaper of the two:
  a step of EDS never costs much more than a step of DSS.
- **No stored pred map.** ``pred`` is derived from g when it is needed: a path follows the
  first neighbour in ``grid.NEIGHBOUR_*`` order with ``g[n] + cost == g[cur]``, exactly
  ``dijkstra.reference_path``, compiled. Keeping a stored pred true to that tie-break rule
  would cost a re-check of every neighbour of every changed cell on each update, to save a
  few hundred look-ups on the one path that is read.
"""

from __future__ import annotations

import time

import numpy as np

from ..field import FieldPlanner
from ..grid import (
    INF,
    NEIGHBOUR_COST,
    NEIGHBOUR_DC,
    NEIGHBOUR_DR,
    Cell,
    in_bounds,
)
from ..interface import UpdateStats
from . import dial as k

CUT_OVER = 0.005
"""Measured on the courtyard walks (dev VM, one interleaved replay of the same deltas): a
repair in which more than about 0.5 % of the map's cells rise costs more than Dijkstra over
the whole map, so EDS computes those from scratch; below it, the repair is far cheaper."""


class FastCpuPlanner(FieldPlanner):
    backend, variant = "cpu", "fast"

    def __init__(
        self, dss: bool = False, queue_capacity: int | None = None, cut_over: float = CUT_OVER
    ) -> None:
        """``queue_capacity``: entries of the bucket queue's pool (default: an eighth of the
        cells, at least 4096); it doubles whenever a call runs out. ``cut_over``: the share of
        the map's cells whose costs may rise in one repair before EDS computes the field from
        scratch instead."""
        super().__init__(dss)
        self._queue_capacity = queue_capacity
        self._cut_over_share = cut_over
        self.cut_over = 1
        self._shape: tuple[int, int] = (0, 0)
        self._goal: Cell = (0, 0)
        self._epoch = 0

    # -- state ------------------------------------------------------------------------------

    def _allocate(self, shape: tuple[int, int]) -> None:
        h, w = shape
        width = w + 2
        n = (h + 2) * width
        self._shape = shape
        self.cut_over = max(1, int(self._cut_over_share * h * w))
        self._blk = np.ones(n, dtype=np.uint8)  # padded: the outer ring stays blocked
        self._g = np.full(n, INF, dtype=np.int32)
        self._ws = np.zeros((n, k.WS_FIELDS), dtype=np.int32)
        self._marked = np.zeros(n, dtype=np.int32)
        capacity = self._queue_capacity or max(4096, n // 8)
        self._pool = np.zeros((capacity, 2), dtype=np.int64)
        self._off = (NEIGHBOUR_DR.astype(np.int64) * width + NEIGHBOUR_DC).astype(np.int64)
        self._cost = NEIGHBOUR_COST.astype(np.int64)

    def _interior(self, flat: np.ndarray) -> np.ndarray:
        h, w = self._shape
        return flat.reshape(h + 2, w + 2)[1:-1, 1:-1]

    def _padded(self, cell: Cell) -> int:
        return (cell[0] + 1) * (self._shape[1] + 2) + cell[1] + 1

    def _next_epoch(self) -> int:
        self._epoch += 1
        if self._epoch >= 2**31 - 1:
            self._ws[:, k.STAMP] = 0
            self._epoch = 1
        return self._epoch

    def _require_plan(self) -> None:
        if self._shape == (0, 0):
            raise RuntimeError("call plan(blocked, goal) before update")

    # -- planning ---------------------------------------------------------------------------

    def plan(self, blocked: np.ndarray, goal: Cell) -> UpdateStats:
        t0 = time.perf_counter()
        self._interior(self._blk)[...] = self._take_plan(blocked, goal)
        return self._dss(t0)

    def _dss(self, t0: float) -> UpdateStats:
        while True:
            pops, touched = k.dss_field(
                self._blk, self._g, self._off, self._cost, self._padded(self._goal),
                self._ws, self._pool,
            )  # fmt: skip
            if pops != k.OVERFLOW:
                return UpdateStats(int(pops), int(touched), (time.perf_counter() - t0) * 1e3)
            self._grow_pool()

    def _grow_pool(self) -> None:
        self._pool = np.zeros((2 * self._pool.shape[0], 2), dtype=np.int64)
        self._ws[:, k.QUEUED] = 0
        self._ws[:, k.MARK] = 0

    def _apply(self, cells: np.ndarray, blocked: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        cells = np.asarray(cells, dtype=np.int64).ravel()
        values = np.broadcast_to(np.asarray(blocked, dtype=bool).ravel(), cells.shape)
        return cells, values.astype(np.uint8)

    def _repair(self, cells: np.ndarray, blocked: np.ndarray) -> UpdateStats:
        t0 = time.perf_counter()
        self._require_plan()
        cells, values = self._apply(cells, blocked)
        h, w = self._shape
        pops, touched = k.eds_update(
            self._blk, self._g, self._off, self._cost, self._padded(self._goal), w, h * w,
            cells, values, self._ws, self._pool, self._marked, self._next_epoch(),
            self.cut_over,
        )  # fmt: skip
        if pops == k.CUT_OVER:  # the map is updated, g is not: recompute it whole
            return self._dss(t0)
        if pops == k.OVERFLOW:  # likewise, with a larger pool
            self._grow_pool()
            return self._dss(t0)
        if pops < 0:
            raise IndexError(f"cell index {int(cells[touched])} is outside the {h}x{w} map")
        return UpdateStats(int(pops), int(touched), (time.perf_counter() - t0) * 1e3)

    def _recompute(self, cells: np.ndarray, blocked: np.ndarray) -> UpdateStats:
        t0 = time.perf_counter()
        self._require_plan()
        cells, values = self._apply(cells, blocked)
        h, w = self._shape
        if cells.size and (cells.min() < 0 or cells.max() >= h * w):
            raise IndexError(f"a cell index is outside the {h}x{w} map")
        rows, cols = cells // w, cells % w
        self._blk[(rows + 1) * (w + 2) + cols + 1] = values
        return self._dss(t0)

    # -- queries ----------------------------------------------------------------------------

    def costs(self) -> np.ndarray:
        return self._interior(self._g).copy()

    def blocked(self) -> np.ndarray:
        return self._interior(self._blk).astype(bool)

    def cost_at(self, cell: Cell) -> int:
        if not in_bounds(self._shape, cell):
            return int(INF)
        return int(self._g[self._padded(cell)])

    def path(self, start: Cell) -> np.ndarray:
        start = (int(start[0]), int(start[1]))
        if not in_bounds(self._shape, start):
            return np.empty((0, 2), dtype=np.int32)
        s = self._padded(start)
        if self._blk[s] or self._g[s] >= INF:
            return np.empty((0, 2), dtype=np.int32)
        return k.path_cells(self._blk, self._g, self._off, self._cost, s, self._shape[1] + 2)
