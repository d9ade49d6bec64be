"""Compiled kernels of the A* planner: an indexed binary heap and the search.

Layout as in ``dial.py``: every map is a flat array over the grid padded by one blocked ring,
so a neighbour is ``v + off[k]`` with no bounds check (``off``/``cost`` follow
``grid.NEIGHBOUR_*``). The per-cell arrays (``g``, ``stamp``, ``pos``, ``par``) and the heap's
two arrays are allocated once per map shape by the caller and reused by every search: a cell's
entries are valid only when ``stamp[v] == epoch`` (the search's number), so a search never
clears n cells — it pays only for the cells it generates.

Heap: a binary min-heap of ``(key, cell)`` in two arrays (``hkey`` int64, ``hcell`` int64)
with ``pos[cell]`` its slot, so a cheaper way to an open cell lowers its key in place
(``_sift_up``) instead of pushing a duplicate; it never holds more than the open cells, so a
capacity of n cells cannot run out. ``pos[v] == CLOSED`` once v is expanded.

Key: ``kg * g + kh * h`` (int64). With ``kh = kg + 1`` it is ``kg * (g + (1 + 1/kg) * h)``:
the f of Ghoniem et al.'s tie-break, ``Break = 1 + 1/(length + width)``, with ``kg`` in the
place of ``length + width`` (see ``astar.py`` for which ``kg`` the planner uses and what
holds then).

Extended A* (Rettkowski et al. 2016, ``extended_astar.py``) runs the same ``search`` with three
switches, all off for classic A*: ``clear_d`` (the memory criterion: a neighbour with a
blocked map cell within ``clear_d`` cells, Chebyshev, is not opened), ``skip_open`` (a
neighbour already in the open list is skipped, never re-evaluated) and ``goal_on_generation``
(the search stops when the goal is generated, their listing's line 9, not when it is popped).
"""

from __future__ import annotations

import math

from numba import njit

from ..grid import INF as _GRID_INF

INF = int(_GRID_INF)
CLOSED = -1

HEURISTICS = ("octile", "chebyshev", "manhattan", "euclidean", "zero")
"""Heuristic names; a kernel takes the index. ``zero`` is Dijkstra (the whole-field search)."""
OCTILE, CHEBYSHEV, MANHATTAN, EUCLIDEAN, ZERO = range(len(HEURISTICS))

STATS = 3
EXPANDED, GENERATED, MAX_OPEN = range(STATS)


@njit(cache=True, nogil=True)
def heuristic(kind, v, goal_r, goal_c, width):
    """Estimated cost (10/14 units) from padded cell ``v`` to the goal at (goal_r, goal_c)."""
    r = v // width
    c = v - r * width
    dr = abs(r - goal_r)
    dc = abs(c - goal_c)
    hi = max(dr, dc)
    lo = min(dr, dc)
    if kind == OCTILE:
        return 10 * hi + 4 * lo
    if kind == CHEBYSHEV:
        return 10 * hi
    if kind == MANHATTAN:
        return 10 * (dr + dc)
    if kind == EUCLIDEAN:
        return int(10.0 * math.sqrt(float(dr * dr + dc * dc)))  # >= 0: truncation is floor
    return 0


@njit(cache=True, nogil=True)
def _sift_up(hkey, hcell, pos, i):
    key = hkey[i]
    v = hcell[i]
    while i > 0:
        parent = (i - 1) >> 1
        if hkey[parent] <= key:
            break
        hkey[i] = hkey[parent]
        hcell[i] = hcell[parent]
        pos[hcell[i]] = i
        i = parent
    hkey[i] = key
    hcell[i] = v
    pos[v] = i


@njit(cache=True, nogil=True)
def _sift_down(hkey, hcell, pos, i, size):
    key = hkey[i]
    v = hcell[i]
    while True:
        child = 2 * i + 1
        if child >= size:
            break
        if child + 1 < size and hkey[child + 1] < hkey[child]:
            child += 1
        if hkey[child] >= key:
            break
        hkey[i] = hkey[child]
        hcell[i] = hcell[child]
        pos[hcell[i]] = i
        i = child
    hkey[i] = key
    hcell[i] = v
    pos[v] = i


@njit(cache=True, nogil=True)
def _push(hkey, hcell, pos, size, v, key):
    """Add v with key to a heap of ``size`` entries; returns the new size."""
    hkey[size] = key
    hcell[size] = v
    _sift_up(hkey, hcell, pos, size)
    return size + 1


@njit(cache=True, nogil=True)
def _pop(hkey, hcell, pos, size):
    """Remove the entry of least key (size > 0); returns (cell, new size)."""
    v = hcell[0]
    size -= 1
    if size > 0:
        hkey[0] = hkey[size]
        hcell[0] = hcell[size]
        _sift_down(hkey, hcell, pos, 0, size)
    pos[v] = CLOSED
    return v, size


@njit(cache=True, nogil=True)
def search(
    blocked, g, stamp, pos, par, hkey, hcell, off, cost, width,
    start, goal, epoch, kind, kg, kh, stats, clear_d=0, skip_open=False,
    goal_on_generation=False,
):  # fmt: skip
    """A* from padded cell ``start`` to ``goal`` (both free), without reopening closed cells.

    The switches (module docstring) are extended A*'s; with their defaults this is A*. A cell
    turned away by the memory criterion is marked closed with g INF (so it is tested once,
    never opened and never counted as generated). Every cell enters the open list at most
    once and leaves it at most once, so a search ends after at most n expansions.

    ``g[v]`` is the cost from ``start`` and ``par[v]`` the neighbour index k of the step
    ``v - off[k] -> v`` that reached v, for every cell with ``stamp[v] == epoch``. ``goal`` -1
    searches the whole component (with ``kind`` ZERO: Dijkstra, exact g everywhere).
    ``stats`` receives expanded, generated (cells first reached, the start included) and the
    largest open-list size. Returns g of the goal, INF when it was not reached.
    """
    goal_r = goal // width if goal >= 0 else 0
    goal_c = goal - goal_r * width if goal >= 0 else 0
    stamp[start] = epoch
    g[start] = 0
    par[start] = -1
    size = _push(hkey, hcell, pos, 0, start, kh * heuristic(kind, start, goal_r, goal_c, width))
    expanded = 0
    generated = 1
    max_open = 1
    found = INF
    while size > 0:
        u, size = _pop(hkey, hcell, pos, size)
        expanded += 1
        if u == goal:
            found = g[u]
            break
        gu = g[u]
        for k in range(8):
            v = u + off[k]
            if blocked[v]:
                continue
            nd = gu + cost[k]
            if stamp[v] != epoch:
                stamp[v] = epoch
                g[v] = nd
                par[v] = k
                if goal_on_generation and v == goal:
                    found = nd
                    generated += 1
                    break
                if clear_d > 0 and v != goal and near_blocked(blocked, v, clear_d, width):
                    g[v] = INF
                    pos[v] = CLOSED
                    continue
                key = kg * nd + kh * heuristic(kind, v, goal_r, goal_c, width)
                size = _push(hkey, hcell, pos, size, v, key)
                generated += 1
            elif pos[v] != CLOSED and nd < g[v] and not skip_open:
                g[v] = nd
                par[v] = k
                hkey[pos[v]] = kg * nd + kh * heuristic(kind, v, goal_r, goal_c, width)
                _sift_up(hkey, hcell, pos, pos[v])
        if size > max_open:
            max_open = size
        if found < INF:
            break
    stats[EXPANDED] = expanded
    stats[GENERATED] = generated
    stats[MAX_OPEN] = max_open
    return found


@njit(cache=True, nogil=True)
def near_blocked(blocked, v, d, width):
    """True when a blocked cell of the map lies within ``d`` cells (Chebyshev: ``d`` steps of
    the 8-connected grid) of padded cell ``v``. The window is clipped to the map: the padding
    ring is not an obstacle, the map's edge is not a wall."""
    rows = blocked.size // width
    r = v // width
    c = v - r * width
    r0 = max(1, r - d)
    r1 = min(rows - 2, r + d)
    c0 = max(1, c - d)
    c1 = min(width - 2, c + d)
    for rr in range(r0, r1 + 1):
        base = rr * width
        for cc in range(c0, c1 + 1):
            if blocked[base + cc]:
                return True
    return False


@njit(cache=True, nogil=True)
def trace(par, off, start, goal, out):
    """The cells from ``start`` to ``goal`` along ``par`` (padded indices into ``out``, start
    first); returns their count, -1 if ``out`` is too short."""
    count = 0
    v = goal
    while True:
        if count >= out.size:
            return -1
        out[count] = v
        count += 1
        if v == start:
            break
        v = v - off[par[v]]
    out[:count] = out[:count][::-1].copy()
    return count


@njit(cache=True, nogil=True)
def field(g, stamp, epoch, out):
    """``out[v] = g[v]`` where this epoch's search reached v, else INF."""
    for v in range(out.size):
        out[v] = g[v] if stamp[v] == epoch else INF


@njit(cache=True, nogil=True)
def window_search(
    blocked, g, stamp, pos, par, hkey, hcell, off, cost, width,
    goal, r0, r1, c0, c1, epoch, stats,
):  # fmt: skip
    """Exact g (cost to ``goal``) of the free cells of the padded window rows [r0, r1) x
    columns [c0, c1): A* from the goal towards the window, heuristic the octile distance to
    the window (consistent: it drops by at most a step's cost), stopped once every free
    window cell is closed. A window cell that is closed holds its exact g; one that is not
    is unreachable (the search ran out). Returns the free window cells left unreached."""
    left = 0
    for r in range(r0, r1):
        for c in range(c0, c1):
            if not blocked[r * width + c]:
                left += 1
    stamp[goal] = epoch
    g[goal] = 0
    par[goal] = -1
    size = _push(hkey, hcell, pos, 0, goal, _to_window(goal, r0, r1, c0, c1, width))
    expanded = 0
    generated = 1
    max_open = 1
    while size > 0 and left > 0:
        u, size = _pop(hkey, hcell, pos, size)
        expanded += 1
        ur = u // width
        uc = u - ur * width
        if r0 <= ur < r1 and c0 <= uc < c1:
            left -= 1
        gu = g[u]
        for k in range(8):
            v = u + off[k]
            if blocked[v]:
                continue
            nd = gu + cost[k]
            if stamp[v] != epoch:
                stamp[v] = epoch
                g[v] = nd
                par[v] = k
                size = _push(hkey, hcell, pos, size, v, nd + _to_window(v, r0, r1, c0, c1, width))
                generated += 1
            elif pos[v] != CLOSED and nd < g[v]:
                g[v] = nd
                par[v] = k
                hkey[pos[v]] = nd + _to_window(v, r0, r1, c0, c1, width)
                _sift_up(hkey, hcell, pos, pos[v])
        if size > max_open:
            max_open = size
    stats[EXPANDED] = expanded
    stats[GENERATED] = generated
    stats[MAX_OPEN] = max_open
    return left


@njit(cache=True, nogil=True)
def _to_window(v, r0, r1, c0, c1, width):
    """Octile distance (10/14) from padded cell v to the nearest cell of the window."""
    r = v // width
    c = v - r * width
    dr = max(r0 - r, 0, r - (r1 - 1))
    dc = max(c0 - c, 0, c - (c1 - 1))
    return 10 * max(dr, dc) + 4 * min(dr, dc)


@njit(cache=True, nogil=True)
def window_field(g, stamp, pos, epoch, r0, r1, c0, c1, width, out):
    """``out[i, j]`` = g of padded cell (r0 + i, c0 + j) when this epoch's search closed it,
    else INF."""
    for r in range(r0, r1):
        for c in range(c0, c1):
            v = r * width + c
            closed = stamp[v] == epoch and pos[v] == CLOSED
            out[r - r0, c - c0] = g[v] if closed else INF
