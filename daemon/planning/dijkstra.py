"""Reference Dijkstra from the goal: simple and obviously right, used by the tests.

Nothing here is fast. It is the yardstick every planner's cost field must equal,
cell for cell, after every map update.
"""

from __future__ import annotations

import heapq

import numpy as np

from .grid import INF, NEIGHBOUR_COST, NEIGHBOUR_DC, NEIGHBOUR_DR, Cell, in_bounds


def dijkstra_field(blocked: np.ndarray, goal: Cell) -> np.ndarray:
    """Exact cost-to-goal of every cell (``int32``, goal 0, INF where unreachable).

    A blocked goal makes every cell unreachable.
    """
    h, w = blocked.shape
    g = np.full((h, w), INF, dtype=np.int32)
    if not in_bounds((h, w), goal) or blocked[goal]:
        return g
    g[goal] = 0
    heap: list[tuple[int, int, int]] = [(0, goal[0], goal[1])]
    while heap:
        d, r, c = heapq.heappop(heap)
        if d > g[r, c]:
            continue
        for dr, dc, cost in zip(NEIGHBOUR_DR, NEIGHBOUR_DC, NEIGHBOUR_COST, strict=True):
            nr, nc = r + int(dr), c + int(dc)
            if 0 <= nr < h and 0 <= nc < w and not blocked[nr, nc]:
                nd = d + int(cost)
                if nd < g[nr, nc]:
                    g[nr, nc] = nd
                    heapq.heappush(heap, (nd, nr, nc))
    return g
