"""The focused EDS repair's queue that outlives a call, and the map changes that fill it.

A binary heap of ``key << 32 | cell`` (``repair.py`` says what the keys are): an entry is live
only while ``qkey[cell]`` still holds its key, so a cell re-keyed is pushed again and its old
entry skipped. ``apply_changes`` writes a change into the map and queues the cells it made
inconsistent; ``repair.settle`` works the queue.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from ..grid import DIAGONAL, STRAIGHT
from .dial import INF, OVERFLOW

SHIFT = 32
CELL = (1 << SHIFT) - 1
ROOM = 9
"""Queue entries one expansion may add: its eight neighbours and the cell itself."""
CUT_OVER = -3
"""Returned past a budget (``apply_changes``: its walk; ``repair.settle``: its expansions):
a plan from scratch is cheaper."""
GOAL_BLOCKED = -4
"""Returned by ``apply_changes`` when the goal became blocked: every cost is INF; recompute."""
OCTILE = DIAGONAL - STRAIGHT


@njit(cache=True, nogil=True, inline="always")
def octile(dr, dc):
    """The user-focused key's heuristic h: the octile distance of a (dr, dc) offset in steps."""
    return STRAIGHT * max(dr, dc) + OCTILE * min(dr, dc)


@njit(cache=True, nogil=True, inline="always")
def look_ahead(g, blk, nb, v):
    """rhs of a cell other than the goal: its best free neighbour's g plus the step there."""
    best = INF
    for k in range(8):
        n = v + nb[k, 0]
        if not blk[n] and g[n] + nb[k, 1] < best:
            best = g[n] + nb[k, 1]
    return best


# -- the heap ------------------------------------------------------------------------------


@njit(cache=True, nogil=True, inline="always")
def sift_down(heap, size, i, entry):
    """Inlined into its callers' compiled code (numba's IR inlining): a call would have numba
    reference-count the heap array on every pop, a third of the worst repair steps' time."""
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


@njit(cache=True, nogil=True, inline="always")
def pool_take(pool, free, used):
    """A bucket entry of ``pool``: the head of the free list, else the next never used.
    Returns (entry, free list's new head, entries used)."""
    if free >= 0:
        return free, pool[free, 1], used
    return used, free, used + 1


@njit(cache=True, nogil=True, inline="always")
def heap_push(heap, hs, entry):
    i = hs[0]
    hs[0] = i + 1
    while i > 0:
        parent = (i - 1) >> 1
        if heap[parent] <= entry:
            break
        heap[i] = heap[parent]
        i = parent
    heap[i] = entry


@njit(cache=True, nogil=True)
def heap_room(heap, hs, qkey, need):
    """True when ``need`` more entries fit, after dropping the stale ones if they do not. False
    also when the live entries fill more than three quarters of the heap: compacting again
    and again would cost more than a larger heap."""
    if hs[0] + need <= heap.size:
        return True
    live = 0
    for i in range(hs[0]):
        e = heap[i]
        if qkey[e & CELL] == e >> SHIFT:
            heap[live] = e
            live += 1
    hs[0] = live
    for i in range(live // 2 - 1, -1, -1):
        sift_down(heap, live, i, heap[i])
    return live + need <= heap.size - heap.size // 4


def live_entries(qkey: np.ndarray) -> int:
    """How many cells wait in the queue (inconsistent cells not yet repaired)."""
    return int(np.count_nonzero(qkey >= 0))


# -- outside the hot loop ------------------------------------------------------------------


@njit(cache=True, nogil=True)
def _to_padded(flat, w):
    return (flat // w + 1) * (w + 2) + flat % w + 1


@njit(cache=True, nogil=True)
def apply_changes(blk, g, rhs, qkey, nb, goal, focus, w, n_cells, cells, values, heap, hs, pool,
                  budget):  # fmt: skip
    """Set ``blk[cells] = values`` (unpadded flat indices) and queue what became inconsistent.

    A newly blocked cell drops to INF at once, and so does, at once, every cell whose every
    look-ahead went through cells that dropped and whose key (``g + h + km``, from its old g)
    lies within the focus's: the part of the shortest-path tree's subtree behind the change
    that the repair would raise before it reaches the user, found by a walk without keys
    (each cell once, no queue) instead of raised one key at a time. Its cells then read their
    look-ahead again from the cells that kept their g, and those that found one wait in the
    queue to be lowered: the repair lowers each of them once, where raising them in key order
    first expanded them twice. A cell of the subtree keyed past the focus keeps its g and
    waits, under-consistent, to be raised in key order if a query ever reaches it (a pocket
    the change closed off far from the user costs nothing now). LPA*'s invariant holds
    throughout — rhs is the exact look-ahead of the g it reads, the queue holds exactly the
    inconsistent cells — and it allows any g, so dropping early is sound. A freed cell reads
    its look-ahead. ``pool``'s rows hold the walk (cell, its old g or -1 if kept); a walk
    longer than them or than ``budget`` returns ``CUT_OVER``: a plan from scratch is cheaper.

    Returns (0, cells whose rhs was read again); (-1, i) when ``cells[i]`` lies outside the
    map (nothing changed); ``GOAL_BLOCKED``, ``CUT_OVER`` or ``OVERFLOW`` (the map is updated,
    the field is not: the caller recomputes it). Loops are written out, not called: numba
    reference-counts the arrays of every call, which cost more than the loops' work.
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
    width, sr, sc, km = focus[3], focus[1], focus[2], focus[4]
    bound = g[focus[0]] + km  # the focus's key as the change comes in
    cap = min(pool.shape[0], budget)
    dropped = 0  # rows of pool: the walk's cells, and their old g (-1: g kept)
    for i in range(cells.size):
        v = _to_padded(cells[i], w)
        if blk[v] and not was[i]:  # newly blocked
            if g[v] < INF:
                if dropped >= cap:
                    return CUT_OVER, 0
                pool[dropped, 0] = v
                pool[dropped, 1] = g[v]
                dropped += 1
            g[v] = rhs[v] = INF
            qkey[v] = -1
    i = 0
    while i < dropped:
        v, gold = pool[i, 0], pool[i, 1]
        i += 1
        if gold < 0:
            continue  # kept its g: no neighbour lost a look-ahead through it
        for k in range(8):
            n = v + nb[k, 0]
            if blk[n] or n == goal or rhs[n] != gold + nb[k, 1]:
                continue
            kept = False  # another neighbour still gives n its look-ahead
            for j in range(8):
                m = n + nb[j, 0]
                if not blk[m] and g[m] + nb[j, 1] == rhs[n]:
                    kept = True
                    break
            if kept:
                continue
            if dropped >= cap:
                return CUT_OVER, 0
            pool[dropped, 0] = n
            r = n // width
            dr, dc = abs(r - sr), abs(n - r * width - sc)
            if g[n] + octile(dr, dc) + km <= bound:
                pool[dropped, 1] = g[n]
                g[n] = INF
            else:  # keyed past the focus: it waits to be raised in key order, if ever
                pool[dropped, 1] = -1
            rhs[n] = INF  # read again below (and not walked into twice)
            dropped += 1
    looks = 0
    for i in range(dropped + cells.size):
        if i < dropped:
            v = pool[i, 0]
            if blk[v]:
                continue
        else:
            v = _to_padded(cells[i - dropped], w)
            if blk[v] or not was[i - dropped]:
                continue  # not newly freed (a freed cell's g is INF: no neighbour read it)
        rhs[v] = 0 if v == goal else look_ahead(g, blk, nb, v)
        looks += 1
        if g[v] == rhs[v]:
            qkey[v] = -1
            continue
        r = v // width
        dr, dc = abs(r - sr), abs(v - r * width - sc)
        key = min(g[v], rhs[v]) + octile(dr, dc) + km
        if qkey[v] != key:
            if hs[0] + 1 > heap.size and not heap_room(heap, hs, qkey, 1):
                return OVERFLOW, 0
            qkey[v] = key
            heap_push(heap, hs, (np.int64(key) << SHIFT) | v)
    return 0, looks
