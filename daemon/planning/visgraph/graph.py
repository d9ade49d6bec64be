"""Points-of-visibility and A* over them (Chen et al., seed 003, §4.1-4.3).

Nodes are the polygons' feature points (vertices) that lie in the map and inside no other
polygon (a vertex inside another obstacle is no point of visibility for anything), plus the
start ``S`` and the goal ``G``, which are attached per query: the polygons, the vertices and
every visibility already judged between two vertices are kept while the map stands, so a new
start or goal costs only the judgements that involve it (§4.4: no rebuilding of the map).

The conflict test (§4.1, eqs. (4) and (5)). Each polygon edge ``AE`` lies on a line
``Ax + By + C = 0`` (eq. (4)); eq. (5) gives the signed distance of a point to it, negative on
the polygon's side. The paper decides "``SG`` conflicts with ``AE``" by the signs of the
distances of ``A`` and ``E`` to the line ``SG`` (opposite signs: conflict; a zero: ``SG``
only touches a feature point, no conflict, since the obstacles are enlarged). That rule alone
judges the infinite line ``SG``, not the segment (it flags an edge beyond ``G``) and passes a
segment that runs from one vertex of a polygon to another through its inside. So the same
signed distances are taken the other way round, of ``S`` and ``G`` to each edge's line, and
the segment is clipped to the polygon's inner side of every edge: ``SG`` conflicts with the
polygon exactly when a piece of positive length is left (touching a feature point or running
along an edge leaves none, the paper's "= 0" case). The paper narrows the edges to test to
those of the feature points nearest ``S``; a tile index over the map does that job here.

The points-of-visibility verdict (§4.2), first phase: a vertex ``v`` of polygon ``p`` can be
a point of visibility for ``M`` only if ``M`` lies on the outer side of one of ``v``'s two
edges (otherwise ``Mv`` enters ``p`` at ``v``). The paper also says at most four feature
points of a polygon with fewer than seven edges are visible from a point; that is not so in
general (a flat hexagon seen along its axis shows all six), so nothing relies on it. Second
phase: ``Mv`` must conflict with no other polygon.

A* (§4.3, eqs. (6), (7)): ``f = g + h``, ``g`` the length travelled, ``h`` the Euclidean
distance to ``G`` (eq. (7) has a sign typo, ``y_m + y_d``; the distance is meant). The open
list is an indexed binary heap; a closed node is not reopened (the Euclidean heuristic is
consistent, so none needs to be). Visibility is judged lazily, when an expansion would
improve a node's ``g``, as the paper's step 5 judges points of visibility of the current
point; each judgement is cached for the pair. A vertex is reached only along a tangent of its
own polygon (``tangent``), the usual pruning of a visibility graph to the edges a shortest
path can use. Dijkstra is the same search with ``h = 0``.
"""

from __future__ import annotations

import numpy as np
from numba import njit

TILE = 8
"""Cells per side of a tile of the polygon index."""
_EPS = 1e-9

# Per-pair visibility cache values.
UNKNOWN, SEEN, HIDDEN = 0, 1, 2

# Statistics slots of a search.
EXPANDED, TESTS, STATS = 0, 1, 2


@njit(cache=True, nogil=True, inline="always")
def _tile(x: float, ntiles: int) -> int:  # pragma: no cover - compiled
    t = int(np.floor((x + 1.0) / TILE))
    return min(max(t, 0), ntiles - 1)


@njit(cache=True, nogil=True)
def build_index(px, py, pn, bbox, th, tw):  # pragma: no cover - compiled
    """CSR lists of the polygons whose box overlaps each tile: (starts, items)."""
    counts = np.zeros(th * tw + 1, dtype=np.int64)
    for p in range(pn.shape[0]):
        for tr in range(_tile(bbox[p, 0], th), _tile(bbox[p, 1], th) + 1):
            for tc in range(_tile(bbox[p, 2], tw), _tile(bbox[p, 3], tw) + 1):
                counts[tr * tw + tc + 1] += 1
    starts = np.cumsum(counts)
    fill = starts[:-1].copy()
    items = np.empty(starts[-1], dtype=np.int32)
    for p in range(pn.shape[0]):
        for tr in range(_tile(bbox[p, 0], th), _tile(bbox[p, 1], th) + 1):
            for tc in range(_tile(bbox[p, 2], tw), _tile(bbox[p, 3], tw) + 1):
                items[fill[tr * tw + tc]] = p
                fill[tr * tw + tc] += 1
    return starts, items


@njit(cache=True, nogil=True)
def conflicts(px, py, n, sx, sy, gx, gy):  # pragma: no cover - compiled
    """Eq. (4)/(5) test: does segment SG enter the open convex polygon (px, py)[:n]?"""
    lo, hi = 0.0, 1.0
    for i in range(n):
        ax, ay = px[i], py[i]
        ex, ey = px[(i + 1) % n], py[(i + 1) % n]
        # Eq. (4): the edge's line A x + B y + C = 0, with (A, B) its outward normal.
        a, b = ey - ay, -(ex - ax)
        norm = np.sqrt(a * a + b * b)
        c = -(a * ax + b * ay)
        ds = (a * sx + b * sy + c) / norm  # eq. (5): > 0 outside, < 0 on the polygon's side
        dg = (a * gx + b * gy + c) / norm
        if ds >= -_EPS and dg >= -_EPS:
            return False  # SG never gets inside this edge: touching at most
        if ds < 0.0 and dg < 0.0:
            continue
        t = ds / (ds - dg)
        if ds > dg:  # entering the edge's inner side (S outside or on the line)
            lo = max(lo, t)
        else:
            hi = min(hi, t)
        if hi <= lo:
            return False
    length = np.sqrt((gx - sx) ** 2 + (gy - sy) ** 2)
    return (hi - lo) * length > 1e-7


@njit(cache=True, nogil=True)
def segment_clear(
    sx, sy, gx, gy, px, py, pn, bbox, starts, items, th, tw, stamp, epoch
):  # pragma: no cover
    """True when SG conflicts with no polygon; only the polygons of the tiles it crosses."""
    epoch[0] += 1
    e = epoch[0]
    r_lo, r_hi = min(sx, gx), max(sx, gx)
    for tr in range(_tile(r_lo, th), _tile(r_hi, th) + 1):
        # The stretch of SG within this tile row, and the tile columns it spans.
        band_lo = max(r_lo, tr * TILE - 1.0)
        band_hi = min(r_hi, (tr + 1) * TILE - 1.0)
        if gx != sx:
            c1 = sy + (gy - sy) * (band_lo - sx) / (gx - sx)
            c2 = sy + (gy - sy) * (band_hi - sx) / (gx - sx)
        else:
            c1, c2 = sy, gy
        for tc in range(_tile(min(c1, c2) - _EPS, tw), _tile(max(c1, c2) + _EPS, tw) + 1):
            t = tr * tw + tc
            for k in range(starts[t], starts[t + 1]):
                p = items[k]
                if stamp[p] == e:
                    continue
                stamp[p] = e
                if bbox[p, 1] < r_lo or bbox[p, 0] > r_hi:
                    continue
                if bbox[p, 3] < min(sy, gy) or bbox[p, 2] > max(sy, gy):
                    continue
                if conflicts(px[p], py[p], pn[p], sx, sy, gx, gy):
                    return False
    return True


@njit(cache=True, nogil=True)
def facing(px, py, n, k, mx, my):  # pragma: no cover - compiled
    """§4.2 first phase: M on the outer side (or the line) of one of vertex k's two edges."""
    for i in ((k - 1) % n, k):
        ax, ay = px[i], py[i]
        ex, ey = px[(i + 1) % n], py[(i + 1) % n]
        if (ey - ay) * (mx - ax) - (ex - ax) * (my - ay) >= -_EPS:
            return True
    return False


@njit(cache=True, nogil=True)
def tangent(px, py, n, k, ux, uy):  # pragma: no cover - compiled
    """Is the line from U through vertex k a tangent of its polygon (both of k's neighbours
    on one side)? A shortest path bends only where it wraps a polygon, so it reaches a vertex
    it turns at along a tangent: a line that cuts the polygon at k leads nowhere useful."""
    vx, vy = px[k], py[k]
    dx, dy = vx - ux, vy - uy
    a = dx * (py[(k - 1) % n] - vy) - dy * (px[(k - 1) % n] - vx)
    b = dx * (py[(k + 1) % n] - vy) - dy * (px[(k + 1) % n] - vx)
    return not ((a > _EPS and b < -_EPS) or (a < -_EPS and b > _EPS))


@njit(cache=True, nogil=True)
def vertices_outside(px, py, pn, bbox, starts, items, th, tw, h, w):  # pragma: no cover
    """Mask over (polygon, vertex) of feature points in the map box and inside no other
    polygon (strictly): the graph's nodes."""
    keep = np.zeros(px.shape, dtype=np.bool_)
    for p in range(pn.shape[0]):
        for k in range(pn[p]):
            x, y = px[p, k], py[p, k]
            if x < -0.5 or x > h - 0.5 or y < -0.5 or y > w - 0.5:
                continue
            inside_other = False
            t = _tile(x, th) * tw + _tile(y, tw)
            for j in range(starts[t], starts[t + 1]):
                q = items[j]
                if q == p:
                    continue
                strictly = True
                n = pn[q]
                for i in range(n):
                    ax, ay = px[q, i], py[q, i]
                    ex, ey = px[q, (i + 1) % n], py[q, (i + 1) % n]
                    if (ex - ax) * (y - ay) - (ey - ay) * (x - ax) <= 1e-7:
                        strictly = False
                        break
                if strictly:
                    inside_other = True
                    break
            keep[p, k] = not inside_other
    return keep


@njit(cache=True, nogil=True)
def _visible(
    u, v, vx, vy, vpoly, vk, vis, px, py, pn, bbox, starts, items, th, tw, stamp, epoch, stats
):  # pragma: no cover - compiled
    """Is the pair (u, v) a line of visibility? Judged once, then read from ``vis``."""
    known = vis[u, v]
    if known != UNKNOWN:
        return known == SEEN
    stats[TESTS] += 1
    pu, pv = vpoly[u], vpoly[v]
    # Phase one (§4.2): each end must face the other across its own polygon's edges.
    ok = (pv < 0 or facing(px[pv], py[pv], pn[pv], vk[v], vx[u], vy[u])) and (
        pu < 0 or facing(px[pu], py[pu], pn[pu], vk[u], vx[v], vy[v])
    )
    if ok:  # phase two: no other polygon in the way
        ok = segment_clear(
            vx[u], vy[u], vx[v], vy[v], px, py, pn, bbox, starts, items, th, tw, stamp, epoch
        )
    vis[u, v] = vis[v, u] = SEEN if ok else HIDDEN
    return ok


@njit(cache=True, nogil=True)
def _push(heap_key, heap_node, pos, size, node, key):  # pragma: no cover - compiled
    i = pos[node]
    if i < 0:
        i = size
        size += 1
    heap_key[i] = key
    heap_node[i] = node
    pos[node] = i
    while i > 0:
        parent = (i - 1) // 2
        if heap_key[parent] <= heap_key[i]:
            break
        heap_key[i], heap_key[parent] = heap_key[parent], heap_key[i]
        heap_node[i], heap_node[parent] = heap_node[parent], heap_node[i]
        pos[heap_node[i]] = i
        pos[heap_node[parent]] = parent
        i = parent
    return size


@njit(cache=True, nogil=True)
def _pop(heap_key, heap_node, pos, size):  # pragma: no cover - compiled
    top = heap_node[0]
    pos[top] = -2  # closed
    size -= 1
    if size > 0:
        heap_key[0] = heap_key[size]
        heap_node[0] = heap_node[size]
        pos[heap_node[0]] = 0
        i = 0
        while True:
            left, right, small = 2 * i + 1, 2 * i + 2, i
            if left < size and heap_key[left] < heap_key[small]:
                small = left
            if right < size and heap_key[right] < heap_key[small]:
                small = right
            if small == i:
                break
            heap_key[i], heap_key[small] = heap_key[small], heap_key[i]
            heap_node[i], heap_node[small] = heap_node[small], heap_node[i]
            pos[heap_node[i]] = i
            pos[heap_node[small]] = small
            i = small
    return top, size


@njit(cache=True, nogil=True)
def search(
    vx,
    vy,
    vpoly,
    vk,
    vis,
    px,
    py,
    pn,
    bbox,
    starts,
    items,
    th,
    tw,
    stamp,
    epoch,
    s,
    goal,
    use_h,
    g,
    parent,
    stats,
):  # pragma: no cover - compiled
    """A* (``use_h``) or Dijkstra from node ``s`` to node ``goal``; the path's length or inf.

    ``g`` and ``parent`` are filled for the nodes reached (``parent`` of ``s`` is -1)."""
    m = vx.shape[0]
    pos = np.full(m, -1, dtype=np.int64)
    heap_key = np.empty(m, dtype=np.float64)
    heap_node = np.empty(m, dtype=np.int64)
    g[:] = np.inf
    parent[:] = -1
    g[s] = 0.0
    size = _push(heap_key, heap_node, pos, 0, s, 0.0)
    gx, gy = vx[goal], vy[goal]
    while size > 0:
        u, size = _pop(heap_key, heap_node, pos, size)
        stats[EXPANDED] += 1
        if u == goal:
            return g[u]
        for v in range(m):
            if pos[v] == -2 or v == u:
                continue
            d = np.sqrt((vx[v] - vx[u]) ** 2 + (vy[v] - vy[u]) ** 2)
            if g[u] + d >= g[v]:
                continue  # no better way: no need to judge its visibility
            p = vpoly[v]
            if v != goal and p >= 0 and not tangent(px[p], py[p], pn[p], vk[v], vx[u], vy[u]):
                continue
            if not _visible(
                u,
                v,
                vx,
                vy,
                vpoly,
                vk,
                vis,
                px,
                py,
                pn,
                bbox,
                starts,
                items,
                th,
                tw,
                stamp,
                epoch,
                stats,
            ):
                continue
            g[v] = g[u] + d
            parent[v] = u
            h = np.sqrt((gx - vx[v]) ** 2 + (gy - vy[v]) ** 2) if use_h else 0.0
            size = _push(heap_key, heap_node, pos, size, v, g[v] + h)
    return np.inf


@njit(cache=True, nogil=True)
def full_graph(
    vx, vy, vpoly, vk, vis, px, py, pn, bbox, starts, items, th, tw, stamp, epoch, stats
):  # pragma: no cover - compiled
    """Judge every pair: the whole visibility graph, as a planner that rebuilds it does."""
    m = vx.shape[0]
    edges = 0
    for u in range(m):
        for v in range(u + 1, m):
            if _visible(
                u,
                v,
                vx,
                vy,
                vpoly,
                vk,
                vis,
                px,
                py,
                pn,
                bbox,
                starts,
                items,
                th,
                tw,
                stamp,
                epoch,
                stats,
            ):
                edges += 1
    return edges
