"""Whether a change's newly blocked cells can have cut anything off: each 8-connected cluster
of them, and whether its contacts (the reached free cells round it) still join up near it.

``Reach.apply`` (``reach.py``) asks this first; the clusters that fail hand their contacts to
``cut_off`` as its seeds. The clusters are found by row runs, not cell by cell: a sensor's
sweep blocks whole areas at once (the 2000² bench walk's first sweep is 119 514 cells in two
clusters of 415 runs, its reveal 137 243 cells in one cluster of 383 runs), and a run's
contacts lie along its ends and the spans above and below it, so the cells inside a cluster
are never visited one by one.
"""

from __future__ import annotations

import numba
import numpy as np

from .cut_off import _root, neighbour_offsets


@numba.njit(cache=True, nogil=True)
def _runs(new, width):
    """The row runs of ``new`` (padded flat cells, each once, in any order): their first
    and last cells (ascending), and their count. A run never wraps to the next row: the
    padded map's border is blocked for good, so no delta names it. The navigator's deltas
    are strictly increasing and ``_flips`` hands the newly blocked back reversed: only a
    delta in neither order is sorted."""
    up = down = True
    for k in range(1, new.size):
        if new[k] <= new[k - 1]:
            up = False
        if new[k] >= new[k - 1]:
            down = False
    cells = new
    if not up and not down:
        cells, up = np.sort(new), True
    n = cells.size
    starts = np.empty(n, dtype=np.int64)
    ends = np.empty(n, dtype=np.int64)
    m = 0
    for k in range(n):
        c = cells[k] if up else cells[n - 1 - k]
        if m and c == ends[m - 1] + 1:
            ends[m - 1] = c
        else:
            starts[m] = c
            ends[m] = c
            m += 1
    return starts, ends, m


@numba.njit(cache=True, nogil=True)
def _linked(starts, ends, m, width):
    """The runs' 8-connected clusters (union-find over the runs of each two adjacent rows):
    ``(head, after)``, each cluster's runs as a list, ``head[r]`` the first of the cluster
    whose root is run r (-1 for a run that is no root), ``after`` the next (-1: the last)."""
    parent = np.arange(m)
    k, prev_lo, prev_hi, prev_row = 0, 0, 0, -2
    while k < m:
        row = starts[k] // width
        e = k
        while e < m and starts[e] // width == row:
            e += 1
        if prev_row == row - 1:
            p = prev_lo
            for i in range(k, e):
                a, b = starts[i] - width, ends[i] - width  # the run's columns, a row up
                while p < prev_hi and ends[p] < a - 1:
                    p += 1
                q = p
                while q < prev_hi and starts[q] <= b + 1:
                    x, y = _root(parent, i), _root(parent, q)
                    if x != y:
                        parent[max(x, y)] = min(x, y)
                    q += 1
        prev_lo, prev_hi, prev_row, k = k, e, row, e
    head = np.full(m, -1, dtype=np.int64)
    after = np.empty(m, dtype=np.int64)
    for i in range(m - 1, -1, -1):
        r = _root(parent, i)
        after[i] = head[r]
        head[r] = i
    return head, after


@numba.njit(cache=True, nogil=True)
def _joined(blocked, width, height, margin, mark, queue, around, mine, wanted, box) -> bool:
    """True when the cluster's contacts ``mine[:wanted]`` (marked 2 in ``mark``, scratch of
    zeros, left zeroed) all connect inside the window round it: its bounding box ``box``
    (rows r0, r1, columns c0, c1 of the padded map) widened by ``margin``."""
    if wanted <= 1:
        if wanted == 1:
            mark[mine[0]] = 0
        return True
    n_mine = wanted
    head, tail = 0, 1
    queue[0] = mine[0]
    mark[mine[0]] = 1
    wanted -= 1
    # The contacts alone first: round a cluster in the open they form one ring, which joins
    # them in O(ring) where the window's breadth-first search covers the cluster's area and
    # more. Then, only if some are still apart, the window from every cell met so far.
    while head < tail and wanted > 0:
        cur = queue[head]
        head += 1
        for o in around:
            j = cur + o
            if mark[j] == 2:
                wanted -= 1
                mark[j] = 1
                queue[tail] = j
                tail += 1
    r0, r1 = max(1, box[0] - margin), min(height - 2, box[1] + margin)
    c0, c1 = max(1, box[2] - margin), min(width - 2, box[3] + margin)
    head = 0
    while head < tail and wanted > 0:
        cur = queue[head]
        head += 1
        # The window's bounds from the cell's own row and column, one division a cell, not
        # two for each of its 8 neighbours: on a 2000² delta of 143 walls whose windows all
        # fail, ``_joined_each`` 55 → 30 ms (dev VM, CPU time, median of 6).
        r, c = cur // width, cur % width
        for d in range(8):
            j = cur + around[d]
            e = d + (d >= 4)  # around skips the cell itself: e is the 3×3 block's index
            rr, cc = r + e // 3 - 1, c + e % 3 - 1
            if blocked[j] or mark[j] == 1 or rr < r0 or rr > r1 or cc < c0 or cc > c1:
                continue
            if mark[j] == 2:
                wanted -= 1
            mark[j] = 1
            queue[tail] = j
            tail += 1
    # Every cell marked 1 is queued; the contacts not met are still 2.
    for k in range(tail):
        mark[queue[k]] = 0
    if wanted > 0:
        for k in range(n_mine):
            mark[mine[k]] = 0
    return wanted == 0


@numba.njit(cache=True, nogil=True)
def _joined_each(blocked, reach, new, width, height, margin, mark, queue, label, contacts,
                 group) -> int:  # fmt: skip
    """``_joined`` for each 8-connected cluster of the newly blocked cells ``new`` (already
    blocked, their reach cleared) in its own window; the contacts of the clusters whose
    contacts do not join there go into ``contacts``, each once; their count is returned (0:
    every cluster's contacts join; a cluster that fails has two or more). Handing
    ``cut_off`` its seeds spares each try a walk over the failed cells' neighbours. Sound: a
    path through new obstacles crosses each cluster from one contact to another, and each
    joined cluster's contacts still join (in the map with every change applied), so a path
    that crossed only joined clusters can be rerouted round them. One window round all of a
    step's changes spans the sensor's sweep (at 2000² a BFS over ~1 M cells: ~4 ms a step);
    a cluster's spans the cluster.

    By runs, not cell by cell (the gather read 8 neighbours of every cell): on the 2000²
    walk's recorded deltas, the first sweep 2.4–2.8 → 0.5–1.1 ms and the reveal 5.3 → 0.8–1.8
    (dev VM, wall clock on an idle machine, warm and cold caches), the same contacts, cuts
    and searches on all 59 deltas at 400² and 2000². ``label``: scratch of zeros, left
    zeroed (3: a contact listed); ``group``: int64 scratch as long as the map, a cluster's
    contacts."""
    around = neighbour_offsets(width)
    starts, ends, m = _runs(new, width)
    head, after = _linked(starts, ends, m, width)
    box = np.empty(4, dtype=np.int64)
    n_contacts = 0
    for root in range(m):
        i = head[root]
        if i < 0:
            continue
        wanted, listed = 0, n_contacts
        box[0], box[1], box[2], box[3] = height, -1, width, -1
        while i >= 0:
            a, b = starts[i], ends[i]
            row = a // width
            box[0], box[1] = min(box[0], row), max(box[1], row)
            box[2], box[3] = min(box[2], a - row * width), max(box[3], b - row * width)
            # The run's two ends, then the spans above and below it, diagonals included.
            # Inline, not a helper: numba counts references to each array a call passes,
            # ~250 ns a cell over the spans (dev VM), ten times the run-free gather's time.
            for t in range(4):
                lo = a - 1 if t != 1 else b + 1
                hi = b + 1 if t >= 2 else lo
                if t == 2:
                    lo, hi = lo - width, hi - width
                elif t == 3:
                    lo, hi = lo + width, hi + width
                for j in range(lo, hi + 1):
                    if blocked[j] or not reach[j] or mark[j] != 0:
                        continue
                    mark[j] = 2
                    group[wanted] = j
                    wanted += 1
                    if label[j] == 0:  # not listed by an earlier cluster that failed
                        label[j] = 3
                        contacts[listed] = j
                        listed += 1
            i = after[i]
        if _joined(blocked, width, height, margin, mark, queue, around, group, wanted, box):
            for k in range(n_contacts, listed):
                label[contacts[k]] = 0
        else:
            n_contacts = listed
    for k in range(n_contacts):
        label[contacts[k]] = 0
    return n_contacts
