"""Compiled kernels of the ``fast`` CPU planner: Dial's bucket queue, raise, lower, path.

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
Seeds with arbitrary keys (the goal, the cells an EDS update re-seeds) are sorted once and
admitted when the level reaches their key.

``ws`` (work space) is an ``int32`` array of ``n x WS_FIELDS`` reused by every call, one row
per cell: a queued flag (raise phase), a mark (1 = invalidated, 2 = freed seed) and the
stamp of the last call that touched it. ``marked`` (``int32``, n) lists the cells marked in
this call.
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
CUT_OVER = -3
"""Returned as the pop count when a repair would cost more than the field from scratch."""
WS_FIELDS = 3
QUEUED, MARK, STAMP = range(WS_FIELDS)


@njit(cache=True)
def _new_queue():
    """Bucket heads (entry index or -1) and ``meta = [free list head, entries used]``."""
    return np.full(NB, -1, np.int64), np.array([-1, 0])


@njit(cache=True)
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


@njit(cache=True)
def _pop(pool, head, meta, b):
    """Take a cell from bucket b (not empty)."""
    e = head[b]
    head[b] = pool[e, 1]
    pool[e, 1] = meta[0]
    meta[0] = e
    return pool[e, 0]


@njit(cache=True)
def _touch(ws, v, epoch):
    if ws[v, STAMP] != epoch:
        ws[v, STAMP] = epoch
        return 1
    return 0


@njit(cache=True)
def _seed_order(g, seeds):
    """The seeds' keys (their g) and the order that admits them level by level (stable)."""
    keys = np.empty(seeds.size, np.int64)
    for i in range(seeds.size):
        keys[i] = g[seeds[i]]
    return keys, np.argsort(keys, kind="mergesort")


@njit(cache=True)
def _level(keys, order, si, pending, level):
    """The level to work at: the next seed's key once the queue has run empty; -1 when the
    seeds are spent too (keys are costs, never negative)."""
    if pending == 0:
        return keys[order[si]] if si < keys.size else -1
    return level


@njit(cache=True)
def lower(blocked, g, off, cost, seeds, ws, pool, epoch):
    """Dijkstra with Dial's buckets from ``seeds`` (``g[seed]`` already holds its key).

    Every other cell's g must be an achievable cost (an upper bound) — true after ``raise_``.
    Returns (pops, cells touched); ``epoch`` 0 skips the touch count (DSS: every cell once).
    """
    keys, order = _seed_order(g, seeds)
    head, meta = _new_queue()
    si = pending = pops = touched = level = 0
    while True:
        level = _level(keys, order, si, pending, level)
        if level < 0:
            break
        # Admit the seeds whose key is this level; a seed lowered meanwhile is already queued.
        while si < seeds.size and keys[order[si]] <= level:
            v = seeds[order[si]]
            if g[v] == keys[order[si]]:
                if not _push(pool, head, meta, v, g[v]):
                    return OVERFLOW, 0
                pending += 1
            si += 1
        b = level % NB
        while head[b] >= 0:
            u = _pop(pool, head, meta, b)
            pending -= 1
            if g[u] != level:
                continue  # a stale entry: u was lowered after this one was pushed
            pops += 1
            if epoch:
                touched += _touch(ws, u, epoch)
            for k in range(8):
                n = u + off[k]
                if blocked[n]:
                    continue
                nd = level + cost[k]
                if nd < g[n]:
                    g[n] = nd
                    if epoch:
                        touched += _touch(ws, n, epoch)
                    if not _push(pool, head, meta, n, nd):
                        return OVERFLOW, 0
                    pending += 1
        level += 1
    return pops, touched


@njit(cache=True)
def _has_support(blocked, g, off, cost, ws, v):
    """True when a neighbour that keeps its g still gives v its g."""
    for k in range(8):
        n = v + off[k]
        if not blocked[n] and ws[n, MARK] == 0 and g[n] + cost[k] == g[v]:
            return True
    return False


@njit(cache=True)
def _give_up(ws, pool, head, meta, marked, first, n_marked):
    """Undo a raise in progress: nothing marked or queued (g was not touched yet)."""
    for i in range(first, n_marked):
        ws[marked[i], MARK] = 0
    for b in range(NB):
        while head[b] >= 0:
            ws[_pop(pool, head, meta, b), QUEUED] = 0


@njit(cache=True)
def raise_(blocked, g, off, cost, seeds, ws, pool, marked, n_marked, epoch, limit):
    """Propagate the inconsistency from newly blocked ``seeds`` (g still the old field).

    A cell is invalidated when every neighbour that supported its g (``g[n] + cost == g[v]``)
    is blocked or invalidated. Candidates — the cells an invalidated neighbour supported —
    are examined in increasing old g, so all their supports are decided first: the
    invalidated set is exactly the cells whose cost rises (when cells are only blocked), not
    the whole predecessor subtree. Marks them (``ws[:, MARK] = 1``), lists them from
    ``marked[n_marked]`` on and sets their g to INF. Returns (new n_marked, pops, touched).

    Past ``limit`` invalidated cells it gives up — marks and queued flags cleared, g as it was
    — and returns ``CUT_OVER`` as the pop count: repairing that many cells costs more than
    computing the field from scratch.
    """
    keys, order = _seed_order(g, seeds)
    head, meta = _new_queue()
    first = n_marked
    si = pending = pops = touched = level = 0
    while True:
        level = _level(keys, order, si, pending, level)
        if level < 0:
            break
        b = level % NB
        while si < seeds.size and keys[order[si]] <= level:
            v = seeds[order[si]]
            si += 1
            if ws[v, MARK] == 0 and ws[v, QUEUED] == 0:
                ws[v, QUEUED] = 1  # a seed is blocked: it never has a support
                if not _push(pool, head, meta, v, level):
                    return n_marked, OVERFLOW, 0
                pending += 1
        while head[b] >= 0:
            v = _pop(pool, head, meta, b)
            ws[v, QUEUED] = 0
            pending -= 1
            pops += 1
            touched += _touch(ws, v, epoch)
            if not blocked[v] and _has_support(blocked, g, off, cost, ws, v):
                continue
            if n_marked - first >= limit:
                _give_up(ws, pool, head, meta, marked, first, n_marked)
                return n_marked, CUT_OVER, 0
            ws[v, MARK] = 1
            marked[n_marked] = v
            n_marked += 1
            for k in range(8):  # queue the cells whose g may have come through v
                n = v + off[k]
                if blocked[n] or ws[n, MARK] != 0 or ws[n, QUEUED] != 0:
                    continue
                if g[n] < INF and g[n] == level + cost[k]:
                    ws[n, QUEUED] = 1
                    if not _push(pool, head, meta, n, g[n]):
                        return n_marked, OVERFLOW, 0
                    pending += 1
        level += 1
    for i in range(first, n_marked):
        g[marked[i]] = INF
    return n_marked, pops, touched


@njit(cache=True)
def _to_padded(flat, w):
    return (flat // w + 1) * (w + 2) + flat % w + 1


@njit(cache=True)
def eds_update(
    blocked, g, off, cost, goal, w, n_cells, cells, values, ws, pool, marked, epoch, limit
):
    """EDS: apply ``blocked[cells] = values`` (unpadded flat indices), repair g.

    1. set inconsistencies: cells now blocked whose g was finite are the raise seeds; cells now
       free whose g is INF (were blocked) become inconsistent.
    2. propagate inconsistency (``raise_``), 3. re-seed every invalidated or freed cell from
    its neighbours, 4. relax until nothing changes (``lower``).
    Returns (pops, cells touched), (-1, i) when ``cells[i]`` lies outside the map (nothing
    changed), (CUT_OVER, 0) when more than ``limit`` cells' costs rise (the map is updated, g
    is not: the caller computes it from scratch), or (OVERFLOW, 0) when the queue's pool ran
    out: the map is then updated but g
    and the marks are not, and the caller must clear ``ws`` and recompute from scratch.
    """
    for i in range(cells.size):
        if cells[i] < 0 or cells[i] >= n_cells:
            return -1, i
    for i in range(cells.size):
        blocked[_to_padded(cells[i], w)] = values[i]
    n_raise = 0
    raise_seeds = np.empty(cells.size, np.int64)
    for i in range(cells.size):
        v = _to_padded(cells[i], w)
        if blocked[v] and g[v] < INF:
            raise_seeds[n_raise] = v
            n_raise += 1
    n_marked, pops, touched = raise_(
        blocked, g, off, cost, raise_seeds[:n_raise], ws, pool, marked, 0, epoch, limit
    )
    if pops in (OVERFLOW, CUT_OVER):
        return pops, 0
    for i in range(cells.size):
        v = _to_padded(cells[i], w)
        if not blocked[v] and g[v] >= INF and ws[v, MARK] == 0:
            ws[v, MARK] = 2
            marked[n_marked] = v
            n_marked += 1
    seeds = np.empty(n_marked, np.int64)
    n_seeds = 0
    for i in range(n_marked):
        v = marked[i]
        ws[v, MARK] = 0
        if blocked[v]:
            continue
        best = g[v]
        if v == goal:
            best = 0
        for k in range(8):
            n = v + off[k]
            if not blocked[n] and g[n] + cost[k] < best:
                best = g[n] + cost[k]
        if best < INF:
            g[v] = best
            touched += _touch(ws, v, epoch)
            seeds[n_seeds] = v
            n_seeds += 1
    lp, lt = lower(blocked, g, off, cost, seeds[:n_seeds], ws, pool, epoch)
    if lp == OVERFLOW:
        return OVERFLOW, 0
    return pops + lp, touched + lt


@njit(cache=True)
def dss_field(blocked, g, off, cost, goal, ws, pool):
    """DSS: g from scratch — INF everywhere, the goal 0, Dijkstra from the goal.

    Returns (pops, pops); pops is OVERFLOW when the queue's pool ran out.
    """
    g[:] = INF
    if blocked[goal]:
        return 0, 0
    g[goal] = 0
    seeds = np.full(1, goal, np.int64)
    pops, _ = lower(blocked, g, off, cost, seeds, ws, pool, 0)
    return pops, pops


@njit(cache=True)
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


def path_cells(blocked, g, off, cost, start: int, width: int) -> np.ndarray:
    """``follow_path`` from padded cell ``start`` as (row, column) pairs of the unpadded map
    (``width``: the padded row length). Raises RuntimeError if g is not a consistent field."""
    out = np.empty(int(g[start]) // 10 + 2, dtype=np.int64)
    n = follow_path(blocked, g, off, cost, start, out)
    if n < 0:
        cell = (start // width - 1, start % width - 1)
        raise RuntimeError(f"g is not a consistent cost field on the way from {cell}")
    return np.stack((out[:n] // width - 1, out[:n] % width - 1), axis=1).astype(np.int32)
