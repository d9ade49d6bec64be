"""The polygon path's segments as 8-connected grid cells, for guidance and the navigator.

Every planner answers ``path(start)`` in cells. A segment of the visibility path is walked
cell by cell (Amanatides and Woo's traversal over cell squares ``[r ± 0.5] x [c ± 0.5]``):
every cell whose square the segment touches, in order, stepping diagonally where it passes
exactly through a corner. Why that stays in free cells: each polygon holds the closed squares
of its blocked cells in its open inside (``polygons.DELTA``), and a line of visibility enters
no polygon, so every square it touches is free. The walk is then thinned: a cell is dropped
when the cells before and after it are neighbours already (a staircase becomes diagonal
steps), which keeps only cells of the walk and every step between 8-neighbours.
"""

from __future__ import annotations

import itertools

import numpy as np
from numba import njit


@njit(cache=True, nogil=True)
def segment_cells(r0, c0, r1, c1, out, n):  # pragma: no cover - compiled
    """Append the cells touched by segment (r0, c0)→(r1, c1) to ``out`` from index ``n``."""
    i, j = int(np.floor(r0 + 0.5)), int(np.floor(c0 + 0.5))
    dr, dc = r1 - r0, c1 - c0
    si = 1 if dr > 0 else -1
    sj = 1 if dc > 0 else -1
    if dr != 0.0:
        t_r = ((i + 0.5 * si) - r0) / dr
        d_r = 1.0 / abs(dr)
    else:
        t_r, d_r = np.inf, np.inf
    if dc != 0.0:
        t_c = ((j + 0.5 * sj) - c0) / dc
        d_c = 1.0 / abs(dc)
    else:
        t_c, d_c = np.inf, np.inf
    out[n, 0], out[n, 1] = i, j
    n += 1
    while min(t_r, t_c) < 1.0 - 1e-12:
        if abs(t_r - t_c) < 1e-12:
            i += si
            j += sj
            t_r += d_r
            t_c += d_c
        elif t_r < t_c:
            i += si
            t_r += d_r
        else:
            j += sj
            t_c += d_c
        out[n, 0], out[n, 1] = i, j
        n += 1
    return n


def rasterise(points: np.ndarray) -> np.ndarray:
    """Cells ``(k, 2) int32`` of the polyline ``points`` (``(m, 2)`` float, row and col)."""
    pts = np.asarray(points, dtype=np.float64)
    bound = 4 + sum(
        int(abs(b[0] - a[0]) + abs(b[1] - a[1])) + 4 for a, b in itertools.pairwise(pts)
    )
    raw = np.empty((bound, 2), dtype=np.int64)
    n = 0
    if len(pts) == 1:
        raw[0] = np.floor(pts[0] + 0.5)
        n = 1
    for a, b in itertools.pairwise(pts):
        n = segment_cells(a[0], a[1], b[0], b[1], raw, n)
    return thin(raw[:n]).astype(np.int32)


def thin(cells: np.ndarray) -> np.ndarray:
    """Drop repeats, and any cell whose neighbours in the walk are 8-neighbours already."""
    stack: list[tuple[int, int]] = []
    for r, c in cells.tolist():
        cell = (r, c)
        if stack and stack[-1] == cell:
            continue
        while len(stack) >= 2 and max(abs(stack[-2][0] - r), abs(stack[-2][1] - c)) <= 1:
            stack.pop()
        if stack and stack[-1] == cell:
            continue
        stack.append(cell)
    return np.array(stack, dtype=np.int64).reshape(-1, 2)
