"""Compiled kernels of the focused EDS repair: ``g``, ``rhs`` and one queue that outlives a call.

Terms are those of LPA* and D* Lite (Koenig and Likhachev 2002), of which the paper's raise and
lower are one schedule: ``g`` is the cost-to-goal field; ``rhs(v)`` is the one-step look-ahead,
the least ``g(n) + c(v, n)`` over the free neighbours ``n`` (0 at the goal, INF on a blocked
cell). A cell is *inconsistent* (the paper's ``incon``) when ``g != rhs``: over-consistent
(``g > rhs``) when a cheaper way opened, under-consistent (``g < rhs``) when its way was cut.
Every inconsistent cell waits in the queue, and no other cell does, under the key

    key(v) = min(g(v), rhs(v)) + h(user, v) + km

with ``h`` the octile distance in the planner's 10/14 units and ``km`` the sum of ``h`` over
the user's moves since the queue was last empty (so that keys queued earlier stay lower bounds).

Why the repair may stop early. Let K be the smallest key in the queue. (1) A consistent cell v
with ``g(v) + h(v) + km < K`` has a neighbour n with ``g(v) = g(n) + c``, whose key is below K
too (h is consistent), so n is consistent: a chain of such cells leads down to the goal and g(v)
is the cost of a real path. (2) Every cell on a shortest path from a cell s with
``g*(s) + h(s) + km < K`` is consistent — an inconsistent one would have a key below K — so by
induction from the goal its g is exact. A path read from the user descends g from ``g(user)``,
and the user's shortest paths, and every neighbour the path's tie-break compares, lie inside
``g* + h <= g*(user)``. So the repair stops once K exceeds ``g(user) + km``, and the path it
reads is the one Dijkstra from scratch gives, tie for tie. What lies outside waits in the queue
until a query reaches it; ``settle`` with ``bounded`` False empties the queue.

The queue. A neighbour's key lies within two edge costs above the key being expanded, so the
wave of one call runs in 29 circular buckets (Dial's queue, ``dial.py``: O(1) a push). Other
keys (a raised cell's new look-ahead past the buckets, the changed cells, what a call leaves)
wait in a binary
heap of ``key << 32 | cell`` that persists between calls (``repair_queue.py``). An entry is
live only while ``qkey[cell]`` still holds its key: a cell re-keyed is pushed again and its old
entry skipped. A full heap is compacted (stale entries dropped); when the live entries still do
not fit, or a call's expansions pass its budget, a call returns ``OVERFLOW`` or ``CUT_OVER`` and
the caller computes the field from scratch, which is always a correct answer.

The hot loop of ``settle`` is written out in one function, heaps included: a numba helper
taking arrays costs their reference counting (two atomic operations an array) on every call.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from ..grid import DIAGONAL
from .dial import INF, OVERFLOW, path_of
from .repair_queue import (
    CELL,
    CUT_OVER,
    ROOM,
    SHIFT,
    apply_changes,
    heap_push,
    heap_room,
    look_ahead,
    octile,
    pool_take,
    sift_down,
)

NBR = 2 * DIAGONAL + 1
"""Buckets of one repair: a neighbour's key lies within twice the largest edge cost above the
key being expanded (one edge, and the heuristic's change along it)."""
BROKEN = -5
"""Returned by ``step`` when the path did not descend g to the goal (never, if g is sound)."""


# -- the repair ----------------------------------------------------------------------------


@njit(cache=True, nogil=True)
def settle(blk, g, rhs, qkey, nb, goal, focus, bound, budget, heap, hs, pool, tie):
    """Repair in key order until the smallest key exceeds ``bound``: -1 means the user's own
    key, ``g(start) + km`` (``h(start, start)`` is 0), as it stands; ``INF`` means until
    nothing is inconsistent.
    ``nb[k]`` is neighbour k's (padded offset, edge cost, row step, column step); ``focus`` is
    (start, its row, its column, padded width, km); ``pool`` holds the buckets' entries;
    ``tie`` orders the cells of one key by ``min(g, rhs)``, as LPA*'s second key does: a cell
    that gives another its look-ahead is expanded first, so that no cell is lowered on a value
    about to be raised.

    The heaps' pushes and pops are written out here rather than called: numba counts the
    references of every array a call passes (two atomic operations each), which cost a
    third of the worst steps' time.

    Returns (expansions, rhs rewrites); (CUT_OVER, 0) past ``budget`` expansions (the field is
    half repaired: the caller computes it from scratch), or (OVERFLOW, 0).
    """
    start, sr, sc, width, km = focus[0], focus[1], focus[2], focus[3], focus[4]
    head = np.full(NBR, -1, np.int64)  # bucket -> its newest entry in pool
    free = -1  # entries given back, linked through pool[e, 1]
    used = 0  # entries ever taken
    pending = 0  # bucket entries, live or stale
    tn = 0  # entries in the tie heap
    pops = touched = 0
    level = 0
    while True:
        if pending == 0:
            if hs[0] == 0:
                break
            level = heap[0] >> SHIFT
        if level > (g[start] + km if bound < 0 else bound):
            break
        b = level % NBR
        # This level's cells from the heap into its bucket.
        while hs[0] > 0 and heap[0] >> SHIFT <= level:
            e = heap[0]
            size = hs[0] - 1
            hs[0] = size
            if size > 0:  # sift the last entry down from the root
                sift_down(heap, size, 0, heap[size])
            v = e & CELL
            if qkey[v] != e >> SHIFT:
                continue  # stale
            r = v // width
            dr, dc = abs(r - sr), abs(v - r * width - sc)
            key = min(g[v], rhs[v]) + octile(dr, dc) + km
            if key > level:  # keyed before the user moved: a lower bound; queue it truly
                qkey[v] = key
                heap_push(heap, hs, (np.int64(key) << SHIFT) | v)
                continue
            if pending + 1 > pool.shape[0]:
                return OVERFLOW, 0
            e, free, used = pool_take(pool, free, used)
            pool[e, 0] = v
            pool[e, 1] = head[b]
            head[b] = e
            pending += 1
        while True:
            # The bucket's cells (and those this level's expansions added) into the tie heap.
            e = head[b]
            head[b] = -1
            while e >= 0:
                v = pool[e, 0]
                nxt = pool[e, 1]
                pool[e, 1] = free
                free = e
                pending -= 1
                if qkey[v] == level:
                    if tn + 1 > tie.size:
                        return OVERFLOW, 0
                    x = (np.int64(min(g[v], rhs[v])) << SHIFT) | v
                    i = tn
                    tn += 1
                    while i > 0:
                        p = (i - 1) >> 1
                        if tie[p] <= x:
                            break
                        tie[i] = tie[p]
                        i = p
                    tie[i] = x
                e = nxt
            if tn == 0:
                break
            v = tie[0] & CELL
            tn -= 1
            if tn > 0:
                sift_down(tie, tn, 0, tie[tn])
            if qkey[v] != level:
                continue  # stale
            if pops >= budget:
                return CUT_OVER, 0
            if pending + ROOM > pool.shape[0] or (
                hs[0] + ROOM > heap.size and not heap_room(heap, hs, qkey, ROOM)
            ):
                return OVERFLOW, 0
            qkey[v] = -1
            pops += 1
            r = v // width
            c = v - r * width
            # Make v consistent: lower it to rhs, or raise it (g = INF) and let the neighbours
            # whose look-ahead came through it look again.
            lowering = g[v] > rhs[v]
            gold = g[v]
            g[v] = rhs[v] if lowering else INF
            for k in range(9):
                if k < 8:
                    n = v + nb[k, 0]
                    if blk[n] or n == goal:
                        continue
                    if lowering:
                        d = g[v] + nb[k, 1]
                        if d >= rhs[n]:
                            continue
                        rhs[n] = d
                    else:
                        if rhs[n] != gold + nb[k, 1]:
                            continue
                        rhs[n] = look_ahead(g, blk, nb, n)
                    touched += 1
                    if g[n] == rhs[n]:
                        qkey[n] = -1
                        continue
                    dr, dc = abs(r + nb[k, 2] - sr), abs(c + nb[k, 3] - sc)
                else:  # v itself, raised: it waits for its new look-ahead
                    n = v
                    if lowering or rhs[v] >= INF:
                        break
                    dr, dc = abs(r - sr), abs(c - sc)
                key = min(g[n], rhs[n]) + octile(dr, dc) + km
                if qkey[n] == key:
                    continue
                qkey[n] = key
                if level <= key < level + NBR:  # a bucket (this level's: its tie heap next)
                    e, free, used = pool_take(pool, free, used)
                    pool[e, 0] = n
                    pool[e, 1] = head[key % NBR]
                    head[key % NBR] = e
                    pending += 1
                else:
                    heap_push(heap, hs, (np.int64(key) << SHIFT) | n)
        level += 1
    # What the buckets still hold waits in the heap for the next call.
    for b in range(NBR):
        e = head[b]
        while e >= 0:
            v = pool[e, 0]
            if qkey[v] >= 0 and qkey[v] % NBR == b:
                if not heap_room(heap, hs, qkey, 1):
                    return OVERFLOW, 0
                heap_push(heap, hs, (np.int64(qkey[v]) << SHIFT) | v)
            e = pool[e, 1]
    return pops, touched


@njit(cache=True, nogil=True)
def step(blk, g, rhs, qkey, nb, off, cost, goal, focus, w, n_cells, cells, values, budget, heap,
         hs, pool, tie):  # fmt: skip
    """One replanning step in one call: ``apply_changes``, ``settle`` up to the user's key
    (``focus`` aimed at the user), the path from the user. Returns (status, expansions, rhs
    rewrites, path): status 0 with the path (empty when the user's cell is blocked or cut
    off), or the status of ``apply_changes`` (its index in the second place for -1) or of
    ``settle``, or ``BROKEN``, with no path."""
    status, touched = apply_changes(blk, g, rhs, qkey, nb, goal, focus, w, n_cells, cells,
                                    values, heap, hs, pool, budget)  # fmt: skip
    none = np.empty((0, 2), dtype=np.int32)
    if status != 0:
        return status, touched, 0, none
    start = focus[0]
    if blk[start]:
        return 0, 0, touched, none
    pops, t = settle(blk, g, rhs, qkey, nb, goal, focus, -1, budget, heap, hs, pool, tie)
    if pops < 0:
        return pops, 0, 0, none
    if g[start] >= INF:
        return 0, pops, touched + t, none
    path = path_of(blk, g, off, cost, start, focus[3])
    if path is None:
        return BROKEN, pops, touched + t, none
    return 0, pops, touched + t, path
