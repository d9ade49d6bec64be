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
GOAL_BLOCKED = -4
"""Returned by ``apply_changes`` when the goal became blocked: every cost is INF; recompute."""
OCTILE = DIAGONAL - STRAIGHT


# -- the heap ------------------------------------------------------------------------------


@njit(cache=True, nogil=True)
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


@njit(cache=True, nogil=True)
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
        _sift_down(heap, live, i, heap[i])
    return live + need <= heap.size - heap.size // 4


def live_entries(qkey: np.ndarray) -> int:
    """How many cells wait in the queue (inconsistent cells not yet repaired)."""
    return int(np.count_nonzero(qkey >= 0))


# -- outside the hot loop ------------------------------------------------------------------


@njit(cache=True, nogil=True)
def _to_padded(flat, w):
    return (flat // w + 1) * (w + 2) + flat % w + 1


@njit(cache=True, nogil=True)
def apply_changes(blk, g, rhs, qkey, nb, goal, focus, w, n_cells, cells, values, heap, hs):
    """Set ``blk[cells] = values`` (unpadded flat indices) and queue what became inconsistent:
    a newly blocked cell drops to INF at once (no neighbour reads a blocked cell) and its
    neighbours that looked through it look again; a freed cell looks at its neighbours.
    The looks are written out in one loop, not called: numba reference-counts the arrays
    of every call, which cost more than the looks themselves.

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
    look = np.empty(8 * cells.size, np.int64)  # cells whose rhs is to be read again
    looks = 0
    for i in range(cells.size):
        v = _to_padded(cells[i], w)
        if blk[v] and not was[i]:  # newly blocked
            gold = g[v]
            g[v] = rhs[v] = INF
            qkey[v] = -1
            if gold >= INF:
                continue
            for k in range(8):
                n = v + nb[k, 0]
                if not blk[n] and n != goal and rhs[n] == gold + nb[k, 1]:
                    look[looks] = n
                    looks += 1
    for i in range(cells.size):
        v = _to_padded(cells[i], w)
        if not blk[v] and was[i]:  # newly freed (g is INF: no neighbour looked through it)
            look[looks] = v
            looks += 1
    width, sr, sc, km = focus[3], focus[1], focus[2], focus[4]
    for i in range(looks):
        v = look[i]
        best = 0 if v == goal else INF
        for k in range(8):
            n = v + nb[k, 0]
            if not blk[n] and g[n] + nb[k, 1] < best:
                best = g[n] + nb[k, 1]
        rhs[v] = best
        if g[v] == rhs[v]:
            qkey[v] = -1
            continue
        r = v // width
        dr, dc = abs(r - sr), abs(v - r * width - sc)
        key = min(g[v], rhs[v]) + STRAIGHT * max(dr, dc) + OCTILE * min(dr, dc) + km
        if qkey[v] != key:
            if hs[0] + 1 > heap.size and not heap_room(heap, hs, qkey, 1):
                return OVERFLOW, 0
            qkey[v] = key
            heap_push(heap, hs, (np.int64(key) << SHIFT) | v)
    return 0, looks
