"""The default CPU planner: the paper's field, repaired only as far as the user needs it.

Choice and why
- **Dial's buckets, compiled with numba** (``dial.py``). Costs are the integers 10 and
  14, so a circular array of 15 buckets is an exact O(1) priority queue: Dijkstra without a
  heap. numba compiles the loops to machine code with no C extension to build, and
  ``cache=True`` compiles them once per machine.
- **DSS** is Dijkstra from the goal over the whole grid, at every change.
- **EDS** repairs the field from the changed cells (``repair.py``, LPA*/D* Lite's ``g`` and
  ``rhs``): the changed cells become inconsistent and wait in a queue that outlives the call,
  keyed ``min(g, rhs) + h(user, cell) + km``; a query works the queue in key order only until
  what it reads is exact — ``path(start)`` until every key left exceeds the user's,
  ``cost_at(cell)`` likewise for that cell, ``costs_within`` for a window, ``costs()`` until the
  queue is empty. A newly seen obstacle that cuts the route raises every cell behind it; the
  user needs only the cells between them and the goal, so the step pays for those, the rest
  waits, and is never paid for if the user walks away from it. A step whose repair would
  expand more than ``CUT_OVER`` of the map computes the field from scratch instead.

  The contract, property-tested against ``dijkstra`` after every change: the path read in a
  step is ``dijkstra.reference_path`` of the current map, tie for tie, and g along it is
  exact; ``cost_at``, ``costs_within`` and ``costs()`` equal ``dijkstra.dijkstra_field`` where
  they read; ``settle()`` makes the whole stored field exact (``pending()`` is then 0).
- **No stored pred map.** ``pred`` is derived from g when it is needed: a path follows the
  first neighbour in ``grid.NEIGHBOUR_*`` order with ``g[n] + cost == g[cur]``, exactly
  ``dijkstra.reference_path``, compiled.
"""

from __future__ import annotations

import time

import numpy as np

from ..field import FieldPlanner
from ..grid import (
    DIAGONAL,
    INF,
    NEIGHBOUR_COST,
    NEIGHBOUR_DC,
    NEIGHBOUR_DR,
    STRAIGHT,
    Cell,
    in_bounds,
)
from ..interface import UpdateStats
from . import dial as k
from . import repair as r
from . import repair_queue as q

CUT_OVER = 0.25
"""A step's repair may expand this share of the map's cells; past it, a plan from scratch (an
expansion costs about three pops of Dijkstra from scratch, measured on the courtyard walks)."""


class FastCpuPlanner(FieldPlanner):
    backend, variant = "cpu", "fast"

    def __init__(
        self, dss: bool = False, queue_capacity: int | None = None, cut_over: float = CUT_OVER
    ) -> None:
        """``queue_capacity``: entries of the bucket pool and of the repair's heap (default: an
        eighth of the cells, at least 4096); both double whenever a call runs out."""
        super().__init__(dss)
        self._queue_capacity = queue_capacity
        self._cut_over = cut_over
        self._shape: tuple[int, int] = (0, 0)
        self._goal: Cell = (0, 0)
        self._aimed = self._km = 0  # the focus's cell and km, as Python ints
        self._no_work = UpdateStats(0, 0, 0.0)

    # -- state ------------------------------------------------------------------------------

    def _allocate(self, shape: tuple[int, int]) -> None:
        h, w = shape
        width = w + 2
        n = (h + 2) * width
        self._shape = shape
        self._blk = np.ones(n, dtype=np.uint8)  # padded: the outer ring stays blocked
        self._g = np.full(n, INF, dtype=np.int32)
        capacity = self._queue_capacity or max(4096, n // 8)
        self._pool = np.zeros((capacity, 2), dtype=np.int64)
        if not self.dss:  # what only the repair keeps between calls
            self._rhs = np.full(n, INF, dtype=np.int32)
            self._qkey = np.full(n, -1, dtype=np.int32)
            self._heap = np.zeros(capacity, dtype=np.int64)
            self._heap_size = np.zeros(1, dtype=np.int64)
            self._tie = np.zeros(capacity, dtype=np.int64)
            self._nb = np.stack(
                [self._off_of(width), NEIGHBOUR_COST, NEIGHBOUR_DR, NEIGHBOUR_DC], axis=1
            ).astype(np.int64)
            """Per neighbour: the padded offset, the edge cost, the row and column steps."""
            self._budget = max(1024, int(self._cut_over * h * w))
            self._focus = np.zeros(5, dtype=np.int64)
            """The repair's focus: the user's cell (padded index, row, column), the padded
            width, and km (D* Lite's sum of the heuristic's shifts as the user moved)."""
        self._off = self._off_of(width)
        self._cost = NEIGHBOUR_COST.astype(np.int64)

    @staticmethod
    def _off_of(width: int) -> np.ndarray:
        return (NEIGHBOUR_DR.astype(np.int64) * width + NEIGHBOUR_DC).astype(np.int64)

    def _interior(self, flat: np.ndarray) -> np.ndarray:
        h, w = self._shape
        return flat.reshape(h + 2, w + 2)[1:-1, 1:-1]

    def _padded(self, cell: Cell) -> int:
        return (cell[0] + 1) * (self._shape[1] + 2) + cell[1] + 1

    def _require_plan(self) -> None:
        if self._shape == (0, 0):
            raise RuntimeError("call plan(blocked, goal) before update")

    # -- planning ---------------------------------------------------------------------------

    def plan(self, blocked: np.ndarray, goal: Cell) -> UpdateStats:
        t0 = time.perf_counter()
        self._interior(self._blk)[...] = self._take_plan(blocked, goal)
        return self._dss(t0)

    def _dss(self, t0: float) -> UpdateStats:
        """The field from scratch; for EDS also rhs = g and an empty queue."""
        while True:
            pops, touched = k.dss_field(
                self._blk, self._g, self._off, self._cost, self._padded(self._goal), self._pool
            )
            if pops != k.OVERFLOW:
                break
            self._pool = np.zeros((2 * self._pool.shape[0], 2), dtype=np.int64)
        if not self.dss:
            self._rhs[:] = self._g
            self._qkey[:] = -1
            self._heap_size[0] = 0
            goal = self._padded(self._goal)
            width = self._shape[1] + 2
            self._focus[:] = (goal, goal // width, goal % width, width, 0)
            self._aimed, self._km = goal, 0
        return UpdateStats(int(pops), int(touched), (time.perf_counter() - t0) * 1e3)

    def _overflowed(self, t0: float) -> UpdateStats:
        """The queue ran out: larger arrays, and the field from scratch (the map is current)."""
        self._pool = np.zeros((2 * self._pool.shape[0], 2), dtype=np.int64)
        self._heap = np.zeros(2 * self._heap.size, dtype=np.int64)
        self._tie = np.zeros(2 * self._tie.size, dtype=np.int64)
        return self._dss(t0)

    def _apply(self, cells: np.ndarray, blocked: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        cells = np.asarray(cells, dtype=np.int64).ravel()
        values = np.asarray(blocked, dtype=bool).ravel()
        if values.size != cells.size:  # one value for every cell (np.broadcast_to: ~5 µs)
            values = np.broadcast_to(values, cells.shape)
        return cells, values.astype(np.uint8)

    def _repair(self, cells: np.ndarray, blocked: np.ndarray) -> UpdateStats:
        """Apply the change and queue what it made inconsistent; queries repair what they read."""
        t0 = time.perf_counter()
        self._require_plan()
        cells, values = self._apply(cells, blocked)
        h, w = self._shape
        status, touched = q.apply_changes(
            self._blk, self._g, self._rhs, self._qkey, self._nb, self._padded(self._goal),
            self._focus, w, h * w, cells, values, self._heap, self._heap_size, self._pool,
            self._budget,
        )  # fmt: skip
        if status == -1:
            raise IndexError(f"cell index {int(cells[touched])} is outside the {h}x{w} map")
        if status in (q.GOAL_BLOCKED, q.CUT_OVER, k.OVERFLOW):
            return self._overflowed(t0) if status == k.OVERFLOW else self._dss(t0)
        return UpdateStats(0, int(touched), (time.perf_counter() - t0) * 1e3)

    def _aim(self, target: int) -> None:
        """Focus the repair on padded cell ``target``: keys queued for the previous focus stay
        lower bounds once km grows by the heuristic's distance between the two (D* Lite).
        Python ints mirror the focus: numpy scalars made this a tenth of a walking step."""
        if target == self._aimed:
            return
        width = self._shape[1] + 2
        r, c = divmod(target, width)
        dr, dc = abs(r - self._aimed // width), abs(c - self._aimed % width)
        self._km += STRAIGHT * max(dr, dc) + (DIAGONAL - STRAIGHT) * min(dr, dc)
        self._aimed = target
        focus = self._focus
        focus[0], focus[1], focus[2], focus[4] = target, r, c, self._km

    def _settle(self, target: int, bound: int = -1) -> UpdateStats:
        """Repair until g is exact along every shortest path from padded cell ``target`` (or,
        with ``bound`` >= 0, for every cell whose g plus its distance from ``target`` plus km
        is at most ``bound``); ``target`` -1: everywhere."""
        if self.dss or not self._heap_size[0]:
            return self._no_work  # nothing is inconsistent: the stored field is exact
        t0 = time.perf_counter()
        if target >= 0:
            self._aim(target)
        else:
            bound = int(INF)
        pops, touched = r.settle(
            self._blk, self._g, self._rhs, self._qkey, self._nb, self._padded(self._goal),
            self._focus, bound, self._budget if target >= 0 else self._g.size,
            self._heap, self._heap_size, self._pool, self._tie,
        )  # fmt: skip
        if pops == q.CUT_OVER:
            return self._dss(t0)
        if pops == k.OVERFLOW:
            return self._overflowed(t0)
        return UpdateStats(int(pops), int(touched), (time.perf_counter() - t0) * 1e3)

    def costs_within(self, r0: int, r1: int, c0: int, c1: int) -> np.ndarray:
        """g over rows ``r0:r1`` and columns ``c0:c1``, exact (what the escape from the
        inflation margin reads): the repair runs, focused on the window's centre, until every
        free cell of it lies below the queue's smallest key; no further."""
        self._require_plan()
        window = self._interior(self._g)[r0:r1, c0:c1]
        if not self.dss:
            free = ~self._interior(self._blk)[r0:r1, c0:c1].astype(bool)
            centre = self._padded(((r0 + r1 - 1) // 2, (c0 + c1 - 1) // 2))
            self._aim(centre)
            rows = np.abs(np.arange(r0, r1) + 1 - int(self._focus[1]))[:, None]
            cols = np.abs(np.arange(c0, c1) + 1 - int(self._focus[2]))[None, :]
            h = STRAIGHT * np.maximum(rows, cols) + (DIAGONAL - STRAIGHT) * np.minimum(rows, cols)
            bound = -1
            while True:
                need = int((window.astype(np.int64) + h)[free].max(initial=0)) + int(self._focus[4])
                if need <= bound or self._heap_size[0] == 0:
                    break
                bound = min(need, int(INF))
                self._settle(centre, bound)
                window = self._interior(self._g)[r0:r1, c0:c1]
        return window.copy()

    def settle(self) -> UpdateStats:
        """Finish the repair everywhere (idle time); afterwards the stored field is exact."""
        self._require_plan()
        return self._settle(-1)

    def pending(self) -> int:
        """Cells still waiting for the repair (0 for DSS, and after ``settle``)."""
        return 0 if self.dss else q.live_entries(self._qkey)

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

    def update_and_path(
        self, cells: np.ndarray, blocked: np.ndarray, start: Cell
    ) -> tuple[UpdateStats, np.ndarray]:
        """EDS: the change, the repair and the path in one compiled call (a walking step pays
        one call's overhead, not three)."""
        start = (int(start[0]), int(start[1]))
        if self.dss or not in_bounds(self._shape, start):
            return super().update_and_path(cells, blocked, start)
        t0 = time.perf_counter()
        cells, values = self._apply(cells, blocked)
        h, w = self._shape
        s = self._padded(start)
        self._aim(s)
        status, pops, touched, path = r.step(
            self._blk, self._g, self._rhs, self._qkey, self._nb, self._off, self._cost,
            self._padded(self._goal), self._focus, w, h * w, cells, values, self._budget,
            self._heap, self._heap_size, self._pool, self._tie,
        )  # fmt: skip
        if status == -1:
            raise IndexError(f"cell index {int(cells[pops])} is outside the {h}x{w} map")
        if status == r.BROKEN:
            raise RuntimeError(f"g is not a consistent cost field on the way from {start}")
        if status != 0:  # the map is updated, the field is not: from scratch
            replanned = self._overflowed(t0) if status == k.OVERFLOW else self._dss(t0)
            pops, touched, path = replanned.iterations, replanned.cells_touched, self.path(start)
        ms = (time.perf_counter() - t0) * 1e3
        return UpdateStats(int(pops), int(touched), ms), path

    # -- queries ----------------------------------------------------------------------------

    def costs(self) -> np.ndarray:
        if self._shape != (0, 0):
            self._settle(-1)
        return self._interior(self._g).copy()

    def blocked(self) -> np.ndarray:
        return self._interior(self._blk).astype(bool)

    def cost_at(self, cell: Cell) -> int:
        if not in_bounds(self._shape, cell):
            return int(INF)
        v = self._padded(cell)
        if self._blk[v]:
            return int(INF)
        self._settle(v)
        return int(self._g[v])

    def path(self, start: Cell) -> np.ndarray:
        return self._path(start)[0]

    def _path(self, start: Cell) -> tuple[np.ndarray, UpdateStats]:
        start = (int(start[0]), int(start[1]))
        if not in_bounds(self._shape, start):
            return np.empty((0, 2), dtype=np.int32), self._no_work
        s = self._padded(start)
        if self._blk[s]:
            return np.empty((0, 2), dtype=np.int32), self._no_work
        stats = self._settle(s)
        if self._g[s] >= INF:
            return np.empty((0, 2), dtype=np.int32), stats
        path = k.path_cells(self._blk, self._g, self._off, self._cost, s, self._shape[1] + 2)
        return path, stats
