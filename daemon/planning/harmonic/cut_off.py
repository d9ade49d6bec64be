"""The reached cells a change cut off from the goal, found from where it happened.

``Reach.apply`` (``reach.py``) runs this for the clusters of newly blocked cells whose free
neighbours no longer join inside a window round them; past its budget, or when the goal's own
region turns out finite, the whole-map search follows.
"""

from __future__ import annotations

import numba
import numpy as np


@numba.njit(cache=True, nogil=True)
def neighbour_offsets(width):
    """The 8 neighbours' offsets in the padded flat map. The searches' inner loops step
    through these rather than work ``(d // 3 - 1) * width + d % 3 - 1`` out for d in 0..8 and
    skip the cell itself: a third of ``cut_off``'s CPU time on the 400² bench walk's tries."""
    return np.array([-width - 1, -width, -width + 1, -1, 1, width - 1, width, width + 1])


@numba.njit(cache=True, nogil=True)
def _root(parent, a):
    while parent[a] != a:
        parent[a] = parent[parent[a]]
        a = parent[a]
    return a


@numba.njit(cache=True, nogil=True)
def cut_off(blocked, reach, seeds, width, goal, group, queue, out, limit) -> int:
    """The reached cells that the clusters ``reach._joined_each`` could not clear cut off from
    the goal, into ``out`` and cleared in ``reach``; returns their count, or -1 for the
    whole-map search: past ``limit`` cells searched, or when the goal's region turns out
    finite (its outside is then unknown). ``seeds``: those clusters' reached free neighbours,
    each once (``_joined_each`` lists them as it gathers the clusters). One breadth-first
    search from many groups at once, each seed one; groups that meet merge (union-find),
    and a group whose frontier runs out is a whole region. A region cut off holds such a
    neighbour (its paths to the goal crossed these clusters, the others can be rerouted), and
    so does the goal's region when any was cut off (or else every neighbour is in it). So
    once at most one group is still growing and the goal is not in a finished one, the
    growing one is the goal's and every finished one is cut off: the search costs about the
    groups times the regions cut off, not the map. ``group``: int32 scratch of zeros, left
    zeroed.

    Seeds past ``limit`` end the try before it searches: it could only give up later. So the
    groups' tables hold at most ``limit`` seeds: on the 2000² 137 k-cell reveal 9 per failed
    cell were two tables of ~1.2 M words, fresh pages each try."""
    if seeds.size > limit:
        return -1
    size = seeds.size + 1
    parent = np.empty(size, dtype=np.int64)
    count = np.zeros(size, dtype=np.int64)
    around = neighbour_offsets(width)
    groups = tail = 0
    for j in seeds:
        groups += 1
        parent[groups], count[groups], group[j] = groups, 1, groups
        queue[tail] = j
        tail += 1
    growing, head, found = groups, 0, 0
    while growing > 1 and head < tail and tail <= limit:
        cur = queue[head]
        head += 1
        own = group[cur]
        a = _root(parent, own)
        count[a] -= 1
        for o in around:
            j = cur + o
            g = group[j]
            # Most neighbours carry cur's own label or its root's (both groups' cells are
            # labelled with the root they had when met): no union-find walk for them.
            if g == own:
                continue
            if g == a or blocked[j]:
                continue
            if g == 0:
                group[j] = a
                count[a] += 1
                queue[tail] = j
                tail += 1
                continue
            b = _root(parent, g)
            if b != a:  # two growing groups meet (a finished one met every neighbour)
                parent[b] = a
                count[a] += count[b]
                growing -= 1
        if count[a] == 0:
            growing -= 1
            if group[goal] != 0 and _root(parent, group[goal]) == a:
                break  # the goal's region is finite: the rest of the map is unknown here
    home = _root(parent, group[goal]) if group[goal] != 0 else 0
    if growing <= 1 and (home == 0 or count[home] > 0) and tail <= limit:
        for k in range(tail):
            c = queue[k]
            if count[_root(parent, group[c])] == 0 and reach[c]:
                reach[c] = False
                out[found] = c
                found += 1
    else:
        found = -1
    for k in range(tail):
        group[queue[k]] = 0
    return found
