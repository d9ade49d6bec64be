"""The host's searches of the padded flat map (8-connected, free cells): breadth-first
from seeds (``flood``: the pockets a freed cell opens, ``reach._grow``), and every cell the
goal reaches, over the map's free runs (``reached_runs``: ``Reach``'s whole-map search where
no device does it).
"""

from __future__ import annotations

import numba
import numpy as np

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


ONES = np.uint64(0x0101010101010101)
"""Eight bool bytes read as one word, every one set."""
BYTE_INDEX = np.uint64(0x0706050403020100)
"""The bytes 7..0: a word with only bit 8·b set, times this, holds 7 − b in its top byte."""


@numba.njit(cache=True, nogil=True)
def free_runs(blocked, starts, ends) -> int:
    """The map's free runs along its rows (maximal runs of free cells in the padded flat map:
    its border is blocked, so none spans two rows), first and last cell into ``starts`` and
    ``ends`` in map order, as far as they hold; returns how many there are.

    The map is read eight cells a word (``blocked``'s bytes as uint64, little-endian),
    each xor'd with itself moved on a byte (the byte before it carried in): a byte of that is
    set where a cell differs from the one before it, so the words with none (on the 400²
    walk's map 18 596 of 20 200) cost one test, and the others one step a change, found as
    the lowest set bit times the bytes 7..0 (its byte's index in the product's top byte)."""
    words = blocked[: blocked.size - blocked.size % 8].view(np.uint64)
    k = 0
    cap = starts.size
    carry = np.uint64(1)  # the cell before the map: the border, blocked
    for j in range(words.size + 1):
        if j < words.size:
            x = words[j]
        else:  # the last cells, fewer than eight (a change past them is none)
            x = np.uint64(0)
            for i in range(blocked.size - 1, 8 * j - 1, -1):
                x = (x << np.uint64(8)) | np.uint64(blocked[i])
        edges = x ^ ((x << np.uint64(8)) | carry)
        carry = x >> np.uint64(56)
        while edges:
            low = edges & (~edges + np.uint64(1))
            edges ^= low
            i = 8 * j + 7 - np.int64((low * BYTE_INDEX) >> np.uint64(56))
            if i >= blocked.size:
                break
            if blocked[i]:
                if k < cap:
                    ends[k] = i - 1
                k += 1
            elif k < cap:
                starts[k] = i
    return k


@numba.njit(cache=True, nogil=True)
def _first_ending(ends, count, shift, starts, out) -> None:
    """``out[k]``: the first run whose end is at or past ``starts[k] + shift`` (a merge: both
    rise with k)."""
    j = 0
    for k in range(count):
        t = starts[k] + shift
        while j < count and ends[j] < t:
            j += 1
        out[k] = j


@numba.njit(cache=True, nogil=True)
def _all_of(mask, words, s, e, value) -> bool:
    """Every one of ``mask[s : e + 1]`` is ``value``; ``words``: ``mask`` eight bytes a word."""
    i = s
    while i <= e and i & 7:
        if mask[i] != value:
            return False
        i += 1
    whole = ONES * np.uint64(value)
    while i + 7 <= e:
        if words[i >> 3] != whole:
            return False
        i += 8
    while i <= e:
        if mask[i] != value:
            return False
        i += 1
    return True


@numba.njit(cache=True, nogil=True)
def reached_runs(blocked, goal, width, reach, was_lost, split_only, runs, flags, stack, lost,
                 gained):  # fmt: skip
    """Every free cell the goal reaches (8-connected), found over the map's free runs rather
    than its cells, and written into ``reach`` with the cells whose reach changed against it:
    the whole-map search of a change that may have cut cells off. ``reach`` holds the reach
    before the change with the newly blocked cells cleared; ``was_lost``: those of them the
    goal reached (sorted). Two runs in neighbouring rows join where they overlap once widened
    by one cell (the diagonals). ``split_only``: the change freed no cell, so each run lies
    inside one run of the map before it, which the goal reached whole or not at all (a run is
    connected): one cell gives the run's old reach; else the run is compared eight cells a
    word. ``runs``: int32 scratch, 4 rows of the runs' capacity; ``flags`` and ``stack`` as
    many. Returns ``(count, n_lost, n_gained)`` with the cells lost and gained in map order in
    ``lost`` and ``gained`` (the newly blocked among the lost), or ``(-runs, 0, 0)`` with
    ``reach`` untouched where the map has more runs than ``runs`` holds.

    The 400² bench walk's map at step 26 holds 811 runs over 85 k free cells: a pass over its
    bytes in words, two merges, a flood over the runs and one cell a run, 0.044 ms (dev VM,
    CPU time), where the scanline fill it replaces took a run at a time cell by cell and then
    compared all 161 k cells' masks (0.33–0.34 ms)."""
    starts, ends, below, above = runs[0], runs[1], runs[2], runs[3]
    n = free_runs(blocked, starts, ends)
    if n > starts.size:
        return -n, 0, 0
    _first_ending(ends, n, width - 1, starts, below)
    _first_ending(ends, n, -width - 1, starts, above)
    flags[:n] = 0
    if not blocked[goal]:
        g = np.searchsorted(ends[:n], goal)
        flags[g] = 1
        stack[0] = g
        top = 1
        while top > 0:
            top -= 1
            k = stack[top]
            s, e = starts[k], ends[k]
            # The row below's runs from the first ending at or past s + width - 1 while they
            # start by e + width + 1; the row above's likewise, a row up.
            for side in range(2):
                j = below[k] if side == 0 else above[k]
                last = e + width + 1 if side == 0 else e - width + 1
                while j < n and starts[j] <= last:
                    if not flags[j]:
                        flags[j] = 1
                        stack[top] = j
                        top += 1
                    j += 1
    reach_words = reach[: reach.size - reach.size % 8].view(np.uint64)
    count = n_lost = n_gained = 0
    b = 0  # the next of was_lost to merge in
    for k in range(n):
        s, e = starts[k], ends[k]
        while b < was_lost.size and was_lost[b] < s:
            lost[n_lost] = was_lost[b]
            n_lost += 1
            b += 1
        if flags[k]:
            count += e - s + 1
        if reach[s] == flags[k] if split_only else _all_of(reach, reach_words, s, e, flags[k]):
            continue
        if flags[k]:
            for i in range(s, e + 1):
                if not reach[i]:
                    reach[i] = True
                    gained[n_gained] = i
                    n_gained += 1
        else:
            for i in range(s, e + 1):
                if reach[i]:
                    reach[i] = False
                    lost[n_lost] = i
                    n_lost += 1
    while b < was_lost.size:
        lost[n_lost] = was_lost[b]
        n_lost += 1
        b += 1
    return count, n_lost, n_gained
