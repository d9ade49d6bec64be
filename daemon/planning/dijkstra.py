"""Reference Dijkstra from the goal and the reference path rule: simple and obviously right.

Nothing here is fast. It is the yardstick every planner's cost field must equal, cell for
cell, after every map update, and the rule every backend's path follows: from a cell, the
first neighbour in ``grid.NEIGHBOUR_*`` order with ``g[n] + cost == g[cur]``.
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


def reference_path(g: np.ndarray, blocked: np.ndarray, start: Cell) -> np.ndarray:
    """Follow predecessors through ``g`` with the fixed neighbour order (pure Python).

    The first neighbour ``n`` in ``grid.NEIGHBOUR_*`` order with ``g[n] + cost == g[cur]``
    is the predecessor. Backends implement the same rule compiled; tests compare with this.
    """
    h, w = g.shape
    if not in_bounds((h, w), start) or blocked[start] or g[start] >= INF:
        return np.empty((0, 2), dtype=np.int32)
    out = [start]
    r, c = start
    while g[r, c] != 0:
        for dr, dc, cost in zip(NEIGHBOUR_DR, NEIGHBOUR_DC, NEIGHBOUR_COST, strict=True):
            nr, nc = r + int(dr), c + int(dc)
            if (
                0 <= nr < h
                and 0 <= nc < w
                and not blocked[nr, nc]
                and int(g[nr, nc]) + int(cost) == int(g[r, c])
            ):
                r, c = nr, nc
                break
        else:
            raise RuntimeError(f"g is not a consistent cost field at {(r, c)}")
        out.append((r, c))
    return np.array(out, dtype=np.int32)


def reference_pred(g: np.ndarray, blocked: np.ndarray) -> np.ndarray:
    """``pred`` map (``int8`` neighbour index, -1 for goal/blocked/unreachable) from g."""
    h, w = g.shape
    pred = np.full((h, w), -1, dtype=np.int8)
    gp = np.pad(g.astype(np.int64), 1, constant_values=int(INF))
    bp = np.pad(blocked, 1, constant_values=True)
    undecided = (~blocked) & (g < INF) & (g > 0)
    for k in range(8):
        dr, dc = int(NEIGHBOUR_DR[k]), int(NEIGHBOUR_DC[k])
        gn = gp[1 + dr : 1 + dr + h, 1 + dc : 1 + dc + w]
        bn = bp[1 + dr : 1 + dr + h, 1 + dc : 1 + dc + w]
        hit = undecided & ~bn & (gn + int(NEIGHBOUR_COST[k]) == g)
        pred[hit] = k
        undecided &= ~hit
    return pred
