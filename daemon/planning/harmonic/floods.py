"""The host's searches of the padded flat map (8-connected, free cells): breadth-first
from seeds (``flood``: the pockets a freed cell opens, ``reach._grow``), and every cell the
goal reaches, by spans (``reached``: ``Reach``'s whole-map search where no device does it).
"""

from __future__ import annotations

import numba

from .cut_off import neighbour_offsets


@numba.njit(cache=True, nogil=True)
def flood(blocked, reach, width, queue, head, tail) -> int:
    """Breadth-first from ``queue[head:tail]`` (already marked in ``reach``) over the free
    cells (8-connected, padded flat map); every cell reached is marked and queued. Returns
    the new tail."""
    around = neighbour_offsets(width)
    while head < tail:
        cur = queue[head]
        head += 1
        for o in around:
            nxt = cur + o
            if not reach[nxt] and not blocked[nxt]:
                reach[nxt] = True
                queue[tail] = nxt
                tail += 1
    return tail


@numba.njit(cache=True, nogil=True)
def reached(blocked, goal, width, reach, stack) -> int:
    """Every free cell the goal reaches (8-connected) into ``reach``; returns their count. The
    whole-map search of a change that may have cut cells off, by spans (a scanline fill): a
    popped cell's run along its row is taken whole, and the rows above and below are read
    one cell past each end (the diagonals) for the runs it touches, each pushed once, by its
    first cell, marked when pushed (so ``stack``, one word a cell, cannot overflow). The
    breadth-first search it replaces (``flood`` from the goal) read 8 neighbours a cell in
    queue order: ~13–19 ns a reached cell, 1.1–1.65 ms on the 400² walk's step 27 (dev VM,
    CPU time); ``bfs_steps`` also counts steps (int64, a plan's first guess, not needed
    here) into a queue it allocates, 32 MB at 2000²."""
    # ``reach`` holds "blocked or taken" while it runs (one load a cell read, not two); the
    # blocked cells are taken out again at the end.
    if blocked[goal]:
        reach[:] = False
        return 0
    reach[:] = blocked
    reach[goal] = True
    stack[0] = goal
    top, count = 1, 0
    while top > 0:
        top -= 1
        c = stack[top]
        lo = c - 1
        while not reach[lo]:
            reach[lo] = True
            lo -= 1
        hi = c + 1
        while not reach[hi]:
            reach[hi] = True
            hi += 1
        count += hi - lo - 1  # lo and hi are past the run's ends, as far as this pop took it
        for row in (-width, width):
            k, end = lo + row, hi + row
            while k <= end:
                if not reach[k]:
                    reach[k] = True
                    stack[top] = k
                    top += 1
                    k += 1
                    # The rest of this run is the popped cell's to take along its row.
                    while k <= end and not reach[k]:
                        k += 1
                else:
                    k += 1
    for i in range(reach.size):
        reach[i] = reach[i] != blocked[i]
    return count
