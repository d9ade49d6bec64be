"""A* between the points of a GA chromosome: the fitness of Ghoniem et al.'s Algorithm 2.

``Segments`` runs the compiled A* of ``astar_kernels.py`` (not a second A*) between two cells
of one map and remembers each answer for the rest of a GA run, where the same segment is
asked for again and again (a chromosome and its copies, its children that keep a gene pair).
``reachable`` is the flood fill that tells which cells a waypoint may be drawn from.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from ..grid import INF, NEIGHBOUR_COST, NEIGHBOUR_DC, NEIGHBOUR_DR, Cell
from . import astar_kernels as k


class Segments:
    """A* between any two cells of one map, remembered per run: the fitness of Algorithm 2.

    Holds the padded map and the per-cell arrays of ``astar_kernels`` (allocated once per map
    shape, told apart per search by an epoch), as ``AStarPlanner`` does."""

    def __init__(self) -> None:
        self.shape: tuple[int, int] = (0, 0)
        self._memo: dict[tuple[int, int], tuple[int, np.ndarray]] = {}
        self.searches = self.expanded = self.max_open = 0

    def load(self, blocked: np.ndarray) -> None:
        """Take the map (``bool``, (h, w)) and forget remembered segments."""
        blocked = np.asarray(blocked, dtype=bool)
        shape = (int(blocked.shape[0]), int(blocked.shape[1]))
        if shape != self.shape:
            h, w = shape
            self.shape, self.width = shape, w + 2
            n = (h + 2) * self.width
            self.blk = np.ones(n, dtype=np.uint8)
            self._g = np.empty(n, dtype=np.int32)
            self._stamp = np.zeros(n, dtype=np.int32)
            self._pos = np.empty(n, dtype=np.int32)
            self._par = np.empty(n, dtype=np.int8)
            self._hkey = np.empty(n, dtype=np.int64)
            self._hcell = np.empty(n, dtype=np.int64)
            self._stats = np.zeros(k.STATS, dtype=np.int64)
            self.off = (NEIGHBOUR_DR.astype(np.int64) * self.width + NEIGHBOUR_DC).astype(np.int64)
            self._cost = NEIGHBOUR_COST.astype(np.int64)
            self._epoch = 0
            # Ties of f by the lower h (astar.py's "exact" key): every segment is optimal.
            self._kg = 20 * (h + w) + 1
        self.blk.reshape(self.shape[0] + 2, self.width)[1:-1, 1:-1] = blocked
        self._memo.clear()
        self.searches = self.expanded = self.max_open = 0

    def padded(self, cell: Cell) -> int:
        return (int(cell[0]) + 1) * self.width + int(cell[1]) + 1

    def cell(self, v: int) -> Cell:
        return (v // self.width - 1, v % self.width - 1)

    def cost(self, a: int, b: int) -> int:
        """A* cost between padded cells ``a`` and ``b`` (INF when none)."""
        return self._segment(a, b)[0]

    def path(self, a: int, b: int) -> np.ndarray:
        """The padded cells of the A* path from ``a`` to ``b`` (empty when none)."""
        return self._segment(a, b)[1]

    def _segment(self, a: int, b: int) -> tuple[int, np.ndarray]:
        key = (a, b)
        hit = self._memo.get(key)
        if hit is not None:
            return hit
        if a == b:
            hit = (0, np.array([a], dtype=np.int64))
        elif self.blk[a] or self.blk[b]:
            hit = (int(INF), np.empty(0, dtype=np.int64))
        else:
            self._epoch += 1
            if self._epoch >= 2**31 - 1:
                self._stamp[:] = 0
                self._epoch = 1
            args = (self.blk, self._g, self._stamp, self._pos, self._par, self._hkey,
                    self._hcell, self.off, self._cost, self.width)  # fmt: skip
            found = int(
                k.search(*args, a, b, self._epoch, k.OCTILE, self._kg, self._kg + 1, self._stats)
            )
            self.searches += 1
            self.expanded += int(self._stats[k.EXPANDED])
            self.max_open = max(self.max_open, int(self._stats[k.MAX_OPEN]))
            cells = np.empty(0, dtype=np.int64)
            if found < INF:
                out = np.empty(found // 10 + 2, dtype=np.int64)
                count = k.trace(self._par, self.off, a, b, out)
                if count < 0:
                    raise RuntimeError("A* predecessors do not lead back to the segment's start")
                cells = out[:count].copy()
            hit = (found, cells)
        self._memo[key] = hit
        return hit


@njit(cache=True, nogil=True)
def reachable(blk, off, start, out):  # pragma: no cover - compiled
    """``out[v] = True`` for every padded cell 8-connected to ``start`` through free cells
    (``start`` free); returns their count. A stack fill: each cell is pushed at most once."""
    stack = np.empty(blk.size, dtype=np.int64)
    stack[0] = start
    out[start] = True
    top = 1
    count = 1
    while top > 0:
        top -= 1
        u = stack[top]
        for j in range(8):
            v = u + off[j]
            if not blk[v] and not out[v]:
                out[v] = True
                stack[top] = v
                top += 1
                count += 1
    return count
