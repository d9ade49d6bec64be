"""Compiled kernels of the ``fast`` CPU planner: Dial's buckets, the field from scratch, a path.

Layout: every map is a flat array over the grid padded by one blocked ring of cells, so a
neighbour is ``v + off[k]`` with no bounds check (``off``/``cost`` follow ``grid.NEIGHBOUR_*``).
Blocked cells always hold ``INF``.

Queue: edge costs are the integers 10 and 14, so every key waiting in a Dijkstra queue lies in
``[level, level + 14]`` (Dial 1969): fifteen circular buckets are an exact priority queue.
Each bucket is a stack of entries ``(cell, next)`` in a pool (``int64``, capacity x 2, owned
by the caller) with a free list; a cell whose g drops is pushed again and its stale entry is
skipped when popped (``g != level``). The pool holds only the frontier — hundreds of entries
on a 400 x 400 grid — so it stays in the first-level cache: measured twice as fast as doubly
linked lists through per-cell links. Should it ever run out, a call returns ``OVERFLOW`` and
the caller recomputes from scratch with a larger pool (growing it inside the loop would cost
numba reference counting on every push: measured 10x slower).
The EDS repair (``repair.py``) uses the same buckets for the wave of one call.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from ..grid import DIAGONAL
from ..grid import INF as _GRID_INF

NB = DIAGONAL + 1
"""Number of buckets: every key waiting lies within the largest edge cost of the level."""
INF = int(_GRID_INF)  # a Python int: numba freezes it as a 64-bit constant, as the loops expect
OVERFLOW = -2
"""Returned as the pop count when the queue's pool of entries ran out."""


@njit(cache=True, nogil=True)
def _new_queue():
    """Bucket heads (entry index or -1) and ``meta = [free list head, entries used]``."""
    return np.full(NB, -1, np.int64), np.array([-1, 0])


@njit(cache=True, nogil=True, inline="always")
def _push(pool, head, meta, v, key):
    """Push cell v with key; False when the pool is full."""
    e = meta[0]
    if e >= 0:
        meta[0] = pool[e, 1]
    else:
        e = meta[1]
        if e == pool.shape[0]:
            return False
        meta[1] = e + 1
    b = key % NB
    pool[e, 0] = v
    pool[e, 1] = head[b]
    head[b] = e
    return True


@njit(cache=True, nogil=True, inline="always")
def _pop(pool, head, meta, b):
    """Take a cell from bucket b (not empty)."""
    e = head[b]
    head[b] = pool[e, 1]
    pool[e, 1] = meta[0]
    meta[0] = e
    return pool[e, 0]


@njit(cache=True, nogil=True)
def dss_field(blocked, g, off, cost, goal, pool):
    """DSS: g from scratch — INF everywhere, the goal 0, Dijkstra with Dial's buckets from it.

    Returns (pops, pops); pops is OVERFLOW when the queue's pool ran out.
    """
    g[:] = INF
    if blocked[goal]:
        return 0, 0
    g[goal] = 0
    head, meta = _new_queue()
    _push(pool, head, meta, goal, 0)
    pending = 1
    pops = level = 0
    while pending > 0:
        b = level % NB
        while head[b] >= 0:
            u = _pop(pool, head, meta, b)
            pending -= 1
            if g[u] != level:
                continue  # a stale entry: u was lowered after this one was pushed
            pops += 1
            for k in range(8):
                n = u + off[k]
                if blocked[n]:
                    continue
                nd = level + cost[k]
                if nd < g[n]:
                    g[n] = nd
                    if not _push(pool, head, meta, n, nd):
                        return OVERFLOW, 0
                    pending += 1
        level += 1
    return pops, pops


@njit(cache=True, nogil=True)
def follow_path(blocked, g, off, cost, start, out):
    """Cells from ``start`` to g == 0: at each cell the first neighbour (in the fixed order)
    with ``g[n] + cost == g[cur]``. Writes padded indices to ``out``; returns their count,
    or -1 if g is not a consistent field."""
    cur = start
    out[0] = cur
    count = 1
    while g[cur] != 0:
        nxt = -1
        for k in range(8):
            n = cur + off[k]
            if not blocked[n] and g[n] + cost[k] == g[cur]:
                nxt = n
                break
        if nxt < 0 or count >= out.size:
            return -1
        cur = nxt
        out[count] = cur
        count += 1
    return count


@njit(cache=True, nogil=True)
def path_of(blocked, g, off, cost, start, width):
    """``follow_path`` from padded cell ``start`` as (row, column) pairs of the unpadded map
    (``width``: the padded row length), ``int32``; None if g is not a consistent field."""
    out = np.empty(g[start] // 10 + 2, dtype=np.int64)
    n = follow_path(blocked, g, off, cost, start, out)
    if n < 0:
        return None
    cells = np.empty((n, 2), dtype=np.int32)
    for i in range(n):
        cells[i, 0] = out[i] // width - 1
        cells[i, 1] = out[i] % width - 1
    return cells


def path_cells(blocked, g, off, cost, start: int, width: int) -> np.ndarray:
    """``path_of``, raising RuntimeError if g is not a consistent field."""
    cells = path_of(blocked, g, off, cost, start, width)
    if cells is None:
        cell = (start // width - 1, start % width - 1)
        raise RuntimeError(f"g is not a consistent cost field on the way from {cell}")
    return cells
