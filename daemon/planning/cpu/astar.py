"""A* from the user's cell to the goal, searched afresh at every path read (Ghoniem et al.).

Where EDS keeps a cost-to-goal field for every cell and repairs it, this planner keeps only
the map: ``plan`` and ``update`` store it (``update`` applies the deltas, nothing more), and
``path(start)`` runs A* from ``start`` to the goal on the 8-connected 10/14 grid of
``grid.py``. Its work depends on the path's surroundings, not on what changed.

Search
- **Open list**: an indexed binary min-heap in numba (``astar_kernels.py``); a cheaper way to
  an open cell lowers its key in place. A closed cell is never reopened (as in the paper's
  listing: "IF u is in N THEN continue").
- **Per-call set-up is O(1)**: the per-cell arrays are allocated once per map shape and a
  search's entries are told apart by a stamp (epoch), so a search on a 1000 x 1000 map pays
  for the cells it generates, not for n.
- **Heuristics** (10/14 units, ``heuristic=``):

  ``octile`` (default) ``10 max(dr, dc) + 4 min(dr, dc)``: the exact cost on an empty grid;
  admissible and consistent.
  ``chebyshev`` ``10 max(dr, dc)``: admissible and consistent (every step costs >= 10 and
  changes max(dr, dc) by at most one); expands more cells than octile.
  ``manhattan`` ``10 (dr + dc)``: NOT admissible here (a diagonal step costs 14 and the
  estimate drops by 20), so its paths may be longer than the optimum.
  ``euclidean`` ``floor(10 sqrt(dr² + dc²))``: NOT admissible here either (a run of k
  diagonal steps costs 14k, the estimate is floor(14.142k)), so its paths may be longer too.

- **Tie-break** (``tie_break=``). The paper orders the open list by
  ``f = g + Break h`` with ``Break = 1 + 1/(length + width)``: among cells of nearly equal
  ``g + h`` the one nearer the goal goes first, so fewer cells are expanded. The key is kept
  in integers as ``(L + W) g + (L + W + 1) h`` — ``(L + W)`` times the paper's f.

  ``exact`` (default; registry variant ``fast``): the same key with ``L + W`` replaced by
  ``S = max h + 1`` (larger than any heuristic value on the map):
  ``S g + (S + 1) h = S (g + h) + h`` orders by ``f = g + h`` and breaks ties of f only, by
  the lower h. What holds exactly: with an admissible and consistent heuristic (octile,
  chebyshev) the path's cost equals the reference Dijkstra's g at the start
  (``dijkstra.dijkstra_field``), after any sequence of map deltas.
  ``paper`` (registry variant ``paper``): the paper's key as it stands. With octile,
  ``Break h`` overestimates by up to ``h / (L + W)`` (up to 14 units), so the search is
  weighted A* with weight ``Break``: with a consistent heuristic and no reopening the
  path's cost ``C`` satisfies ``C <= Break C*``, i.e. ``(L + W) C <= (L + W + 1) C*``, and is
  often but not always optimal (measured: 1 miss in 14,609 random queries on maps up to
  60 x 60, by 0.6 %; ``tests/daemon/planning/test_astar.py`` tests exactly this bound and
  holds a 9 x 4 map where it misses).
  ``none``: ``f = g + h``, ties in the heap's order.

What differs from EDS/DSS
- The path has the optimal cost (``exact`` with octile or chebyshev) but need not be the
  same cells as ``reference_path``: ties between equal-cost paths are broken by the search,
  not by ``grid.NEIGHBOUR_*`` order.
- ``cost_at(cell)`` runs the search from ``cell`` and gives its path's cost (INF if the cell
  is blocked, outside or cut off): the optimum under the conditions above.
  ``costs_within(r0, r1, c0, c1)`` — what the escape from the inflation margin reads — is
  the exact g of a window: one A* from the goal towards the window (the grid is undirected),
  stopped once the window's free cells are settled. ``costs()`` is the whole exact field,
  one Dijkstra from the goal, O(n log n).
- CPU only: the registry builds it for every backend (``cuda``, ``auto``, ``reference``).

Statistics: ``UpdateStats.iterations`` is the cells expanded, ``cells_touched`` the cells
generated; ``max_open`` the largest open-list size of the last search; ``search_stats`` the
statistics of the last search (the navigator reports it for a path read without a change).
"""

from __future__ import annotations

import time

import numpy as np

from ..grid import (
    INF,
    NEIGHBOUR_COST,
    NEIGHBOUR_DC,
    NEIGHBOUR_DR,
    Cell,
    checked_plan_input,
    checked_update_input,
    in_bounds,
)
from ..interface import GlobalPlanner, UpdateStats
from . import astar_kernels as k

HEURISTICS = k.HEURISTICS[:-1]
"""The heuristics a planner can use (``zero`` is kept for the whole-field search)."""
TIE_BREAKS = ("exact", "paper", "none")
ADMISSIBLE = ("octile", "chebyshev")
"""Heuristics that never overestimate on this grid (and are consistent)."""

_EMPTY = np.empty((0, 2), dtype=np.int32)


class AStarPlanner(GlobalPlanner):
    backend = "cpu"

    def __init__(self, heuristic: str = "octile", tie_break: str = "exact") -> None:
        if heuristic not in HEURISTICS:
            raise ValueError(f"unknown heuristic {heuristic!r}; choose one of {HEURISTICS}")
        if tie_break not in TIE_BREAKS:
            raise ValueError(f"unknown tie_break {tie_break!r}; choose one of {TIE_BREAKS}")
        self.heuristic = heuristic
        self.tie_break = tie_break
        self.variant = {"exact": "fast", "paper": "paper", "none": "plain"}[tie_break]
        self.name = f"astar-cpu-{heuristic}" + ("" if tie_break == "exact" else f"-{tie_break}")
        self._kind = k.HEURISTICS.index(heuristic)
        # Extended A*'s switches (``extended_astar.py``); off, this is classic A*.
        self._clear_d = 0
        self._skip_open = False
        self._goal_on_generation = False
        self._shape: tuple[int, int] = (0, 0)
        self._goal: Cell = (0, 0)
        self._epoch = 0
        self._version = 0
        self._cached: tuple[tuple[Cell, int], np.ndarray, int] | None = None
        self.max_open = 0
        """The largest open-list size of the last search."""
        self.search_stats: UpdateStats | None = None
        """Expanded / generated cells and wall time of the last search (None before one)."""

    # -- state ------------------------------------------------------------------------------

    def _allocate(self, shape: tuple[int, int]) -> None:
        h, w = shape
        width = w + 2
        n = (h + 2) * width
        self._shape = shape
        self._width = width
        self._blk = np.ones(n, dtype=np.uint8)  # padded: the outer ring stays blocked
        self._g = np.empty(n, dtype=np.int32)
        self._stamp = np.zeros(n, dtype=np.int32)
        self._pos = np.empty(n, dtype=np.int32)
        self._par = np.empty(n, dtype=np.int8)
        self._hkey = np.empty(n, dtype=np.int64)
        self._hcell = np.empty(n, dtype=np.int64)
        self._stats = np.zeros(k.STATS, dtype=np.int64)
        self._off = (NEIGHBOUR_DR.astype(np.int64) * width + NEIGHBOUR_DC).astype(np.int64)
        self._cost = NEIGHBOUR_COST.astype(np.int64)
        self._epoch = 0
        # Key = kg g + kh h; see the module's docstring.
        if self.tie_break == "exact":
            s = 20 * (h + w) + 1  # every heuristic here is at most 14 (dr + dc) < s
            self._kg, self._kh = s, s + 1
        elif self.tie_break == "paper":
            self._kg, self._kh = h + w, h + w + 1
        else:
            self._kg, self._kh = 1, 1

    def _padded(self, cell: Cell) -> int:
        return (cell[0] + 1) * self._width + cell[1] + 1

    def _interior(self, flat: np.ndarray) -> np.ndarray:
        h, w = self._shape
        return flat.reshape(h + 2, w + 2)[1:-1, 1:-1]

    def _next_epoch(self) -> int:
        self._epoch += 1
        if self._epoch >= 2**31 - 1:
            self._stamp[:] = 0
            self._epoch = 1
        return self._epoch

    def _require_plan(self) -> None:
        if self._shape == (0, 0):
            raise RuntimeError("call plan(blocked, goal) before update")

    @property
    def goal(self) -> Cell:
        return self._goal

    @property
    def shape(self) -> tuple[int, int]:
        return self._shape

    # -- the map ----------------------------------------------------------------------------

    def plan(self, blocked: np.ndarray, goal: Cell) -> UpdateStats:
        """Store the map and the goal; no search (there is no start yet)."""
        t0 = time.perf_counter()
        blocked, shape, goal = checked_plan_input(blocked, goal)
        if shape != self._shape:
            self._allocate(shape)
        self._goal = goal
        self._interior(self._blk)[...] = blocked
        self._version += 1
        return UpdateStats(0, 0, (time.perf_counter() - t0) * 1e3)

    def update(self, cells: np.ndarray, blocked: np.ndarray) -> UpdateStats:
        """Apply ``blocked[cells] = blocked``; no search. ``cells_touched`` = cells written."""
        t0 = time.perf_counter()
        cells, values = checked_update_input(self._shape, cells, blocked)
        w = self._shape[1]
        if cells.size:
            self._blk[(cells // w + 1) * self._width + cells % w + 1] = values
            self._version += 1
        return UpdateStats(0, int(cells.size), (time.perf_counter() - t0) * 1e3)

    def blocked(self) -> np.ndarray:
        """A copy of the stored map (``bool``, (h, w))."""
        return self._interior(self._blk).astype(bool)

    # -- searches ---------------------------------------------------------------------------

    def _search(self, start: Cell) -> tuple[np.ndarray, int]:
        """(path, cost) from ``start``; (empty, INF) when there is none."""
        start = (int(start[0]), int(start[1]))
        if not in_bounds(self._shape, start):
            return _EMPTY, int(INF)
        key = (start, self._version)
        if self._cached is not None and self._cached[0] == key:
            return self._cached[1], self._cached[2]
        t0 = time.perf_counter()
        s, goal = self._padded(start), self._padded(self._goal)
        self._stats[:] = 0
        cost = int(INF)
        path = _EMPTY
        if not (self._blk[s] or self._blk[goal]):
            found = k.search(
                self._blk, self._g, self._stamp, self._pos, self._par, self._hkey, self._hcell,
                self._off, self._cost, self._width, s, goal, self._next_epoch(), self._kind,
                self._kg, self._kh, self._stats, self._clear_d, self._skip_open,
                self._goal_on_generation,
            )  # fmt: skip
            cost = int(found)
            if cost < INF:
                out = np.empty(cost // 10 + 2, dtype=np.int64)
                count = k.trace(self._par, self._off, s, goal, out)
                if count < 0:
                    raise RuntimeError("A* predecessors do not lead back to the start")
                out = out[:count]
                path = np.stack((out // self._width - 1, out % self._width - 1), axis=1)
                path = path.astype(np.int32)
        self.max_open = int(self._stats[k.MAX_OPEN])
        self.search_stats = UpdateStats(
            int(self._stats[k.EXPANDED]),
            int(self._stats[k.GENERATED]),
            (time.perf_counter() - t0) * 1e3,
        )
        self._cached = (key, path, cost)
        return path, cost

    def path(self, start: Cell) -> np.ndarray:
        return self._search(start)[0].copy()

    def cost_at(self, cell: Cell) -> int:
        return self._search(cell)[1]

    def update_and_path(
        self, cells: np.ndarray, blocked: np.ndarray, start: Cell
    ) -> tuple[UpdateStats, np.ndarray]:
        """``update`` then ``path``: ``iterations`` expanded, ``cells_touched`` generated."""
        t0 = time.perf_counter()
        self.update(cells, blocked)
        path = self.path(start)
        stats = self.search_stats
        expanded, generated = (stats.iterations, stats.cells_touched) if stats else (0, 0)
        return UpdateStats(expanded, generated, (time.perf_counter() - t0) * 1e3), path

    def costs_within(self, r0: int, r1: int, c0: int, c1: int) -> np.ndarray:
        """The exact cost-to-goal of the cells of rows [r0, r1) x columns [c0, c1) (clipped
        to the map; ``int32``, INF where blocked or unreachable): one A* from the goal
        towards the window, stopped once every free cell of it is settled. What the escape
        from the margin reads: a window around the user, not the whole field."""
        self._require_plan()
        h, w = self._shape
        r0, r1 = max(0, int(r0)), min(h, int(r1))
        c0, c1 = max(0, int(c0)), min(w, int(c1))
        out = np.full((max(0, r1 - r0), max(0, c1 - c0)), INF, dtype=np.int32)
        goal = self._padded(self._goal)
        if out.size and not self._blk[goal]:
            epoch = self._next_epoch()
            k.window_search(
                self._blk, self._g, self._stamp, self._pos, self._par, self._hkey, self._hcell,
                self._off, self._cost, self._width, goal, r0 + 1, r1 + 1, c0 + 1, c1 + 1, epoch,
                self._stats,
            )  # fmt: skip
            k.window_field(self._g, self._stamp, self._pos, epoch, r0 + 1, r1 + 1, c0 + 1,
                           c1 + 1, self._width, out)  # fmt: skip
        return out

    def costs(self) -> np.ndarray:
        """The exact cost-to-goal of every cell (``int32``, (h, w), INF where unreachable):
        one Dijkstra from the goal."""
        self._require_plan()
        out = np.empty(self._blk.size, dtype=np.int32)
        goal = self._padded(self._goal)
        if self._blk[goal]:
            out[:] = INF
        else:
            epoch = self._next_epoch()
            k.search(
                self._blk, self._g, self._stamp, self._pos, self._par, self._hkey, self._hcell,
                self._off, self._cost, self._width, goal, -1, epoch, k.ZERO, 1, 0,
                self._stats,
            )  # fmt: skip
            k.field(self._g, self._stamp, epoch, out)
        return self._interior(out).copy()
