"""Compiled kernels of the focused EDS repair: ``g``, ``rhs`` and one queue that outlives a call.

Terms are those of LPA* (Koenig, Likhachev and Furcy 2004), of which the paper's raise and
lower are one schedule: ``g`` is the cost-to-goal field; ``rhs(v)`` is the one-step look-ahead,
the least ``g(n) + c(v, n)`` over the free neighbours ``n`` (0 at the goal, INF on a blocked
cell). A cell is *inconsistent* (the paper's ``incon``) when ``g != rhs``: over-consistent
(``g > rhs``) when a cheaper way opened, under-consistent (``g < rhs``) when its way was cut.
Every inconsistent cell waits in the queue under the key ``min(g, rhs)``, and no other cell does.

Why the repair may stop early. When every key in the queue is greater than K, every cell with
``g < K`` holds its exact cost: a consistent cell below K has a neighbour that gives it its g,
so a chain of such cells leads down to the goal (g is the cost of a real path), and a cell
whose exact cost is below K cannot be cheaper than g without an inconsistent cell below K on
its way. A path from the user descends g from ``g(user)``, and every neighbour it compares
lies below ``g(user)`` too; so the repair stops once the smallest key exceeds ``g(user)``,
and the path it reads is the one Dijkstra from scratch gives, tie for tie. What lies farther
from the goal than the user (the rest of a raise wave, fields behind the user) stays queued
until a query reaches it; ``settle`` with no target empties the queue.

The queue has two parts. Keys within the edge costs above the level being worked sit in Dial's
fifteen buckets (``dial.py``): the wave of one call, O(1) a push. Keys far above it (a raised
cell's new look-ahead, the changed cells, whatever a call leaves) wait in a binary heap of
``key << 32 | cell``, which persists between calls. An entry is live only while
``qkey[cell]`` still holds its key; a cell re-keyed is pushed again and its old entry skipped.
When the heap fills it is compacted (stale entries dropped); should the live ones still not
fit, a call returns ``OVERFLOW`` and the caller recomputes the field from scratch with larger
arrays, which is always a correct answer.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from .dial import INF, OVERFLOW, _new_queue, _pop, _push
from ..grid import DIAGONAL, STRAIGHT

SHIFT = 32
CELL = (1 << SHIFT) - 1
NBR = 2 * DIAGONAL + 1
"""Buckets of one repair: a neighbour's key lies within twice the largest edge cost of the
key being expanded (one edge, and the heuristic's change along it)."""
ROOM = 9
"""Queue entries one expansion may add: its eight neighbours and the cell itself."""
GOAL_BLOCKED = -4
"""Returned by ``apply_changes`` when the goal became blocked: every cost is INF; recompute."""


# -- the heap ------------------------------------------------------------------------------


@njit(cache=True, inline="always")
def _sift_down(heap, size, i, entry):
    while True:
        c = 2 * i + 1
        if c >= size:
            break
        if c + 1 < size and heap[c + 1] < heap[c]:
            c += 1
        if heap[c] >= entry:
            break
        heap[i] = heap[c]
        i = c
    heap[i] = entry


@njit(cache=True, inline="always")
def _heap_push(heap, hs, entry):
    i = hs[0]
    hs[0] = i + 1
    while i > 0:
        parent = (i - 1) >> 1
        if heap[parent] <= entry:
            break
        heap[i] = heap[parent]
        i = parent
    heap[i] = entry


@njit(cache=True, inline="always")
def _heap_pop(heap, hs):
    top = heap[0]
    size = hs[0] - 1
    hs[0] = size
    if size > 0:
        _sift_down(heap, size, 0, heap[size])
    return top


@njit(cache=True, inline="always")
def _heap_room(heap, hs, qkey, need):
    """True when ``need`` more entries fit, after dropping the stale ones if they do not. False
    also when the live entries fill more than three quarters of the heap: compacting again
    and again would cost more than a larger heap."""
    return hs[0] + need <= heap.size or _compact(heap, hs, qkey, need)


@njit(cache=True)
def _compact(heap, hs, qkey, need):
    live = 0
    for i in range(hs[0]):
        e = heap[i]
        if qkey[e & CELL] == e >> SHIFT:
            heap[live] = e
            live += 1
    hs[0] = live
    for i in range(live // 2 - 1, -1, -1):
        _sift_down(heap, live, i, heap[i])
    return live + need <= heap.size - heap.size // 4


def live_entries(qkey: np.ndarray) -> int:
    """How many cells wait in the queue (inconsistent cells not yet repaired)."""
    return int(np.count_nonzero(qkey >= 0))


# -- one cell ------------------------------------------------------------------------------


@njit(cache=True, inline="always")
def _lookahead(blk, g, off, cost, v):
    """rhs(v) from its free neighbours (not for the goal, whose rhs is 0)."""
    best = INF
    for k in range(8):
        n = v + off[k]
        if not blk[n]:
            d = g[n] + cost[k]
            if d < best:
                best = d
    return best


@njit(cache=True, inline="always")
def _key(g, rhs, v, focus):
    """min(g, rhs) + h(start, v) + km: octile distance from the user's cell in 10/14 units,
    plus what the user's moves since the queue's oldest keys took off them."""
    dr = abs(v // focus[3] - focus[1])
    dc = abs(v % focus[3] - focus[2])
    h = STRAIGHT * max(dr, dc) + (DIAGONAL - STRAIGHT) * min(dr, dc)
    return min(g[v], rhs[v]) + h + focus[4]


@njit(cache=True, inline="always")
def _requeue(g, rhs, qkey, v, focus, level, heap, hs, pool, head, meta):
    """Queue v under its key if it is inconsistent (forget it if not). A key within the
    buckets' reach of ``level`` goes to a bucket, any other to the heap (``level`` -1: outside a
    repair, always the heap). Returns 1 when a bucket entry was added."""
    if g[v] == rhs[v]:
        qkey[v] = -1
        return 0
    key = _key(g, rhs, v, focus)
    if qkey[v] == key:
        return 0
    qkey[v] = key
    if level >= 0 and level <= key < level + NBR:
        _push(pool, head, meta, v, key)
        return 1
    _heap_push(heap, hs, (np.int64(key) << SHIFT) | v)
    return 0


@njit(cache=True, inline="always")
def _cut_from(blk, g, rhs, qkey, off, cost, goal, v, gold, focus, level, heap, hs, pool,
              head, meta):
    """v's g is gone (it was ``gold``): neighbours whose look-ahead came through v look again."""
    queued = 0
    touched = 0
    for k in range(8):
        n = v + off[k]
        if blk[n] or n == goal or rhs[n] != gold + cost[k]:
            continue
        rhs[n] = _lookahead(blk, g, off, cost, n)
        touched += 1
        queued += _requeue(g, rhs, qkey, n, focus, level, heap, hs, pool, head, meta)
    return queued, touched


@njit(cache=True, inline="always")
def _expand(blk, g, rhs, qkey, off, cost, goal, v, focus, level, heap, hs, pool, head, meta):
    """Make v consistent: lower it to rhs, or raise it (g = INF) and queue it under its rhs.
    Returns (bucket entries added, cells whose rhs was rewritten)."""
    if g[v] > rhs[v]:  # over-consistent: its cost is rhs, final at this level
        gv = rhs[v]
        g[v] = gv
        queued = 0
        touched = 0
        for k in range(8):
            n = v + off[k]
            if blk[n] or n == goal:
                continue
            d = gv + cost[k]
            if d < rhs[n]:
                rhs[n] = d
                touched += 1
                queued += _requeue(g, rhs, qkey, n, focus, level, heap, hs, pool, head, meta)
        return queued, touched
    gold = g[v]  # under-consistent: what v gave its neighbours is no longer there
    g[v] = INF
    queued, touched = _cut_from(blk, g, rhs, qkey, off, cost, goal, v, gold, focus, level, heap,
                                hs, pool, head, meta)  # fmt: skip
    queued += _requeue(g, rhs, qkey, v, focus, level, heap, hs, pool, head, meta)
    return queued, touched


# -- calls ---------------------------------------------------------------------------------


@njit(cache=True, inline="always")
def _to_padded(flat, w):
    return (flat // w + 1) * (w + 2) + flat % w + 1


@njit(cache=True)
def apply_changes(blk, g, rhs, qkey, off, cost, goal, focus, w, n_cells, cells, values, heap, hs):
    """Set ``blk[cells] = values`` (unpadded flat indices) and queue what became inconsistent:
    a newly blocked cell drops to INF at once (no neighbour reads a blocked cell) and its
    neighbours that looked through it look again; a freed cell looks at its neighbours.

    Returns (0, cells whose rhs was rewritten); (-1, i) when ``cells[i]`` lies outside the map
    (nothing changed); ``GOAL_BLOCKED`` or ``OVERFLOW`` (the map is updated, the field is not:
    the caller recomputes it).
    """
    for i in range(cells.size):
        if cells[i] < 0 or cells[i] >= n_cells:
            return -1, i
    was = np.empty(cells.size, np.uint8)
    for i in range(cells.size):
        was[i] = blk[_to_padded(cells[i], w)]
    for i in range(cells.size):
        blk[_to_padded(cells[i], w)] = values[i]
    if blk[goal]:
        return GOAL_BLOCKED, 0
    head, meta = _new_queue()  # unused outside a repair: every key goes to the heap
    pool = np.empty((0, 2), np.int64)
    touched = 0
    for i in range(cells.size):
        v = _to_padded(cells[i], w)
        if not blk[v] or was[i]:
            continue
        gold = g[v]
        g[v] = INF
        rhs[v] = INF
        qkey[v] = -1
        if gold < INF:
            if not _heap_room(heap, hs, qkey, ROOM):
                return OVERFLOW, 0
            _, t = _cut_from(blk, g, rhs, qkey, off, cost, goal, v, gold, focus, -1, heap, hs,
                             pool, head, meta)  # fmt: skip
            touched += t
    for i in range(cells.size):
        v = _to_padded(cells[i], w)
        if blk[v] or not was[i]:
            continue
        rhs[v] = 0 if v == goal else _lookahead(blk, g, off, cost, v)
        touched += 1
        if not _heap_room(heap, hs, qkey, 1):
            return OVERFLOW, 0
        _requeue(g, rhs, qkey, v, focus, -1, heap, hs, pool, head, meta)
    return 0, touched


@njit(cache=True)
def settle(blk, g, rhs, qkey, off, cost, goal, focus, bounded, heap, hs, pool):
    """Repair in key order. ``bounded``: until the smallest key exceeds the user's own,
    ``g(start) + km`` (with ``h(start, start)`` 0); else until nothing is inconsistent.
    Returns (expansions, rhs rewrites), or (OVERFLOW, 0)."""
    head, meta = _new_queue(NBR)
    start = focus[0]
    pending = 0  # bucket entries, live or stale
    pops = touched = 0
    level = 0
    while True:
        if pending == 0:
            if hs[0] == 0:
                break
            level = heap[0] >> SHIFT
        if bounded and level > g[start] + focus[4]:
            break
        b = level % NBR
        while True:  # every entry keyed at level, from the heap or the bucket
            if hs[0] > 0 and heap[0] >> SHIFT <= level:
                e = _heap_pop(heap, hs)
                v = e & CELL
                if qkey[v] != e >> SHIFT:
                    continue
            elif head[b] >= 0:
                v = _pop(pool, head, meta, b)
                pending -= 1
                if qkey[v] != level:
                    continue
            else:
                break
            if pending + ROOM > pool.shape[0] or not _heap_room(heap, hs, qkey, ROOM):
                return OVERFLOW, 0
            key = _key(g, rhs, v, focus)
            if key > level:  # keyed before the user moved: a lower bound; queue it truly
                qkey[v] = -1
                pending += _requeue(g, rhs, qkey, v, focus, level, heap, hs, pool, head, meta)
                continue
            qkey[v] = -1
            pops += 1
            queued, t = _expand(blk, g, rhs, qkey, off, cost, goal, v, focus, level, heap, hs,
                                pool, head, meta)  # fmt: skip
            pending += queued
            touched += t + 1
        level += 1
    # What the buckets still hold waits in the heap for the next call.
    for b in range(NBR):
        while head[b] >= 0:
            v = _pop(pool, head, meta, b)
            if qkey[v] >= 0 and qkey[v] % NBR == b:
                if not _heap_room(heap, hs, qkey, 1):
                    return OVERFLOW, 0
                _heap_push(heap, hs, (np.int64(qkey[v]) << SHIFT) | v)
    return pops, touched
