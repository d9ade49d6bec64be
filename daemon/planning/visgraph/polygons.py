"""The blocked grid as Chen et al.'s obstacle polygons: convex, fewer than seven edges each.

Chen, Tang, Jin (seed 003) §2.1: obstacles are "similar polygons" enlarged by ``ω/2 + a``
(ω the robot's width, ``a`` its positional uncertainty, 15 cm); only convex polygons with
fewer than seven edges are kept, and a concave or round obstacle is "expanded" to such polygons.

What is enlarged by what, here
- The planner receives guidebelt's ``blocked`` map, which the navigator has already inflated
  (``inflation.py``, ``navigation/map_keeper.py``): a cell is blocked when its centre lies
  within the user's radius of an occupied cell's centre. That radius (``user_radius_m`` in the
  config, 0.30 m by default) plays the paper's ``ω/2 + a``: it is the user's half width plus
  whatever margin for localisation the config puts in it. It is NOT added again here.
- The pieces below cover every blocked cell's whole square (not only its centre), so the
  polygons reach up to half a cell beyond where the inflation judged a cell blocked: the
  geometric price of turning cells into polygons, at most ``cell_m / 2`` per side (5 cm).
- Every piece is pushed out by ``DELTA`` cells (``offset``): the closed squares of blocked
  cells then lie in the polygons' open interiors, so a segment that enters no polygon touches
  free cells only, and pieces cut from one obstacle overlap rather than meet on a line (a
  segment could otherwise slip along the seam between two halves).
- ``extra_cells`` (default 0) enlarges every piece further, for a caller that wants the
  paper's ``a`` on top of an inflation that holds ``ω/2`` alone.
- The map is cut in blocks of ``CUT_TILE`` cells and each block's 8-connected components
  into pieces, so a change cuts its block again and no more (``PolygonMap``).
- A piece never covers a free cell's centre: a convex piece that would (an L-shaped wall's
  hull, a disc's hexagon that bulges over a free cell) is split in two across its longer side
  and each half tried again, down to single cells if need be. So the user's cell and the goal,
  free on the grid, are never inside a polygon, and the polygons close a passage only where
  its free cells touch diagonally alone (the offset shuts a corner-to-corner gap).

Coordinates are ``(row, col)`` in cells; cell ``(r, c)`` is the square
``[r - 0.5, r + 0.5] x [c - 0.5, c + 0.5]``, its centre ``(r, c)``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numba import njit

MAX_EDGES = 6
"""The paper's "edge number less than seven"."""
DELTA = 0.02
"""Outward offset of every piece, in cells (see the module's docstring)."""
_EPS = 1e-9


@dataclass(frozen=True, slots=True)
class Piece:
    """One convex obstacle polygon: vertices counter-clockwise in (row, col), ``(k, 2)``."""

    vertices: np.ndarray
    cells: int
    """Blocked cells this piece was cut to cover."""


@njit(cache=True, nogil=True)
def label_components(blocked: np.ndarray) -> tuple[np.ndarray, int]:  # pragma: no cover
    """8-connected components of ``blocked``: labels (0 = free, 1..n) and n."""
    h, w = blocked.shape
    labels = np.zeros((h, w), dtype=np.int32)
    stack = np.empty(h * w, dtype=np.int64)
    n = 0
    for r0 in range(h):
        for c0 in range(w):
            if not blocked[r0, c0] or labels[r0, c0] != 0:
                continue
            n += 1
            labels[r0, c0] = n
            top = 0
            stack[0] = r0 * w + c0
            top = 1
            while top > 0:
                top -= 1
                r = stack[top] // w
                c = stack[top] % w
                for dr in range(-1, 2):
                    for dc in range(-1, 2):
                        rr = r + dr
                        cc = c + dc
                        if rr < 0 or rr >= h or cc < 0 or cc >= w:
                            continue
                        if blocked[rr, cc] and labels[rr, cc] == 0:
                            labels[rr, cc] = n
                            stack[top] = rr * w + cc
                            top += 1
    return labels, n


@njit(cache=True, nogil=True, inline="always")
def _cross(ox, oy, ax, ay, bx, by):  # pragma: no cover - compiled
    return (ax - ox) * (by - oy) - (ay - oy) * (bx - ox)


@njit(cache=True, nogil=True)
def convex_hull(points: np.ndarray) -> np.ndarray:  # pragma: no cover - compiled
    """Andrew's monotone chain; counter-clockwise in (row, col) as x, y; no collinear points."""
    order = np.argsort(points[:, 1], kind="mergesort")
    order = order[np.argsort(points[order, 0], kind="mergesort")]  # by row, then col
    m = order.size
    hull = np.empty((2 * m + 1, 2), dtype=np.float64)
    k = 0
    for half in range(2):  # the lower chain forwards, then the upper chain backwards
        base = k
        for j in range(m):
            idx = order[j] if half == 0 else order[m - 1 - j]
            x, y = points[idx, 0], points[idx, 1]
            if k > 0 and hull[k - 1, 0] == x and hull[k - 1, 1] == y:
                continue
            while (
                k - base >= 2
                and _cross(hull[k - 2, 0], hull[k - 2, 1], hull[k - 1, 0], hull[k - 1, 1], x, y)
                <= _EPS
            ):
                k -= 1
            hull[k, 0], hull[k, 1] = x, y
            k += 1
        k -= 1  # each chain's last point is the other's first
    return hull[: max(k, 0)].copy()


@njit(cache=True, nogil=True, inline="always")
def _line_meet(x1, y1, x2, y2, x3, y3, x4, y4):  # pragma: no cover - compiled
    """Where line 12 meets line 34: (found, x, y); not found if they are parallel."""
    d1x, d1y, d2x, d2y = x2 - x1, y2 - y1, x4 - x3, y4 - y3
    den = d1x * d2y - d1y * d2x
    if abs(den) < _EPS:
        return False, 0.0, 0.0
    t = ((x3 - x1) * d2y - (y3 - y1) * d2x) / den
    return True, x1 + t * d1x, y1 + t * d1y


@njit(cache=True, nogil=True)
def reduce_edges(poly: np.ndarray, max_edges: int = MAX_EDGES) -> np.ndarray:  # pragma: no cover
    """A convex polygon with at most ``max_edges`` edges that contains ``poly``.

    Greedy: drop the edge whose removal (extending its two neighbours to their meeting point)
    adds the least area, while more than ``max_edges`` remain. An edge can be dropped only
    when its neighbours turn by less than 180° together, else they never meet on its side.
    """
    v = poly.copy()
    n = v.shape[0]
    while n > max_edges:
        best, best_area, bx, by = -1, np.inf, 0.0, 0.0
        for i in range(n):
            a, b = i, (i + 1) % n
            prev, nxt = (i - 1) % n, (i + 2) % n
            ok, x, y = _line_meet(
                v[prev, 0], v[prev, 1], v[a, 0], v[a, 1], v[b, 0], v[b, 1], v[nxt, 0], v[nxt, 1]
            )
            if not ok:
                continue
            # x must lie beyond a along prev→a (and beyond b along nxt→b): outside the edge.
            if (x - v[a, 0]) * (v[a, 0] - v[prev, 0]) + (y - v[a, 1]) * (v[a, 1] - v[prev, 1]) <= 0:
                continue
            if (x - v[b, 0]) * (v[b, 0] - v[nxt, 0]) + (y - v[b, 1]) * (v[b, 1] - v[nxt, 1]) <= 0:
                continue
            area = 0.5 * abs(_cross(v[a, 0], v[a, 1], x, y, v[b, 0], v[b, 1]))
            if area < best_area:
                best, best_area, bx, by = i, area, x, y
        if best < 0:  # cannot happen for a convex polygon with more than four edges
            raise ValueError("no edge of the polygon can be dropped")
        v[best, 0], v[best, 1] = bx, by
        drop = (best + 1) % n
        v[drop : n - 1] = v[drop + 1 : n].copy()
        n -= 1
    return v[:n].copy()


@njit(cache=True, nogil=True)
def offset(poly: np.ndarray, d: float) -> np.ndarray:  # pragma: no cover - compiled
    """The convex polygon with every edge moved outward by ``d`` (counter-clockwise input)."""
    n = poly.shape[0]
    lines = np.empty((n, 4), dtype=np.float64)
    for i in range(n):
        ax, ay = poly[i, 0], poly[i, 1]
        ex, ey = poly[(i + 1) % n, 0] - ax, poly[(i + 1) % n, 1] - ay
        norm = np.sqrt(ex * ex + ey * ey)
        nx, ny = ey / norm, -ex / norm  # outward for counter-clockwise (row, col)
        lines[i] = (ax + d * nx, ay + d * ny, ax + ex + d * nx, ay + ey + d * ny)
    out = np.empty_like(poly)
    for i in range(n):
        p, q = lines[(i - 1) % n], lines[i]
        ok, x, y = _line_meet(p[0], p[1], p[2], p[3], q[0], q[1], q[2], q[3])
        out[i, 0], out[i, 1] = (x, y) if ok else (q[0], q[1])
    return out


def covers(poly: np.ndarray, rows: np.ndarray, cols: np.ndarray) -> np.ndarray:
    """Points (rows, cols) inside or on the convex counter-clockwise polygon ``poly``."""
    inside = np.ones(rows.shape, dtype=bool)
    n = len(poly)
    for i in range(n):
        a, b = poly[i], poly[(i + 1) % n]
        side = (b[0] - a[0]) * (cols - a[1]) - (b[1] - a[1]) * (rows - a[0])
        inside &= side >= -1e-7
    return inside


@njit(cache=True, nogil=True)
def _hull_of_cells(rows: np.ndarray, cols: np.ndarray) -> np.ndarray:  # pragma: no cover
    """Hull of the squares of the cells: only each row's outermost cells can add corners."""
    r0 = rows.min()
    span = rows.max() - r0 + 1
    lo = np.full(span, np.iinfo(np.int64).max)
    hi = np.full(span, np.iinfo(np.int64).min)
    for i in range(rows.size):
        k = rows[i] - r0
        lo[k] = min(lo[k], cols[i])
        hi[k] = max(hi[k], cols[i])
    pts = np.empty((8 * span, 2), dtype=np.float64)
    m = 0
    for k in range(span):
        if lo[k] > hi[k]:
            continue
        for c in (lo[k], hi[k]):
            for dr in (-0.5, 0.5):
                for dc in (-0.5, 0.5):
                    pts[m, 0], pts[m, 1] = r0 + k + dr, c + dc
                    m += 1
    return convex_hull(pts[:m])


@njit(cache=True, nogil=True)
def _try_piece(free, rows, cols, grow):  # pragma: no cover - compiled
    """The enlarged convex polygon of these cells, or an empty one if it would cover a centre
    that ``free`` marks (or one beyond ``free``'s bounds, which is taken as free)."""
    poly = offset(reduce_edges(_hull_of_cells(rows, cols)), DELTA + grow)
    h, w = free.shape
    n = poly.shape[0]
    r0, r1 = int(np.floor(poly[:, 0].min())), int(np.ceil(poly[:, 0].max()))
    c0, c1 = int(np.floor(poly[:, 1].min())), int(np.ceil(poly[:, 1].max()))
    for r in range(r0, r1 + 1):
        for c in range(c0, c1 + 1):
            inside = True
            for i in range(n):
                ax, ay = poly[i, 0], poly[i, 1]
                bx, by = poly[(i + 1) % n, 0], poly[(i + 1) % n, 1]
                if (bx - ax) * (c - ay) - (by - ay) * (r - ax) < -1e-7:
                    inside = False
                    break
            if inside and (r < 0 or r >= h or c < 0 or c >= w or free[r, c]):
                return poly[:0]
    return poly


def _split(rows: np.ndarray, cols: np.ndarray) -> list[tuple[np.ndarray, np.ndarray]]:
    """Halves across the longer side of the cells' box, each cut into its 8-connected parts."""
    if np.ptp(rows) >= np.ptp(cols):
        side = rows <= (rows.min() + rows.max()) // 2
    else:
        side = cols <= (cols.min() + cols.max()) // 2
    parts = []
    for half in (side, ~side):
        r, c = rows[half], cols[half]
        if r.size == 0:
            continue
        sub = np.zeros((np.ptp(r) + 1, np.ptp(c) + 1), dtype=np.bool_)
        sub[r - r.min(), c - c.min()] = True
        labels, n = label_components(sub)
        for k in range(1, n + 1):
            lr, lc = np.nonzero(labels == k)
            parts.append((lr + r.min(), lc + c.min()))
    return parts


def component_pieces(
    free: np.ndarray, rows: np.ndarray, cols: np.ndarray, grow: float = 0.0
) -> list[Piece]:
    """Convex pieces (< 7 edges, enlarged) covering these cells and no free centre."""
    out: list[Piece] = []
    todo = [(rows, cols)]
    while todo:
        r, c = todo.pop()
        poly = _try_piece(free, r, c, grow)
        if len(poly):
            out.append(Piece(poly, int(r.size)))
        else:  # a single cell's square never covers another centre, so this ends
            todo.extend(_split(r, c))
    return out


CUT_TILE = 16
"""Cells per side of the blocks the map is cut in: a change cuts its block again, no more."""


def tile_pieces(tile: np.ndarray, r0: int, c0: int, grow: float = 0.0) -> list[Piece]:
    """Pieces of one block of the map whose top-left cell is (r0, c0), in map coordinates.

    Cells beyond the block count as free: no piece covers a centre outside its block, so a
    block's pieces depend on the block alone and can be kept while it does not change."""
    labels, n = label_components(tile)
    out = []
    for k in range(1, n + 1):
        rows, cols = np.nonzero(labels == k)
        for piece in component_pieces(~tile, rows, cols, grow):
            moved = piece.vertices + np.array([r0, c0], dtype=np.float64)
            out.append(Piece(moved, piece.cells))
    return out


class PolygonMap:
    """The pieces of the map, block by block (``CUT_TILE``), cut again only where a block's
    cells changed: each block is known by its position and the bytes of its cells."""

    def __init__(self, extra_cells: float = 0.0) -> None:
        self.extra_cells = float(extra_cells)
        self._cache: dict[tuple[int, int], tuple[bytes, list[Piece]]] = {}
        self.pieces: list[Piece] = []
        self.cut = 0
        """Blocks cut into pieces at the last build (the others' pieces were kept)."""

    def build(self, blocked: np.ndarray) -> list[Piece]:
        """The pieces of ``blocked``; blocks unchanged since the last build keep theirs."""
        blocked = np.ascontiguousarray(blocked, dtype=np.bool_)
        h, w = blocked.shape
        cache: dict[tuple[int, int], tuple[bytes, list[Piece]]] = {}
        pieces: list[Piece] = []
        self.cut = 0
        for r0 in range(0, h, CUT_TILE):
            for c0 in range(0, w, CUT_TILE):
                tile = blocked[r0 : r0 + CUT_TILE, c0 : c0 + CUT_TILE]
                key = tile.tobytes() + bytes(tile.shape)
                old = self._cache.get((r0, c0))
                if old is not None and old[0] == key:
                    got = old[1]
                else:
                    got = tile_pieces(np.ascontiguousarray(tile), r0, c0, self.extra_cells)
                    self.cut += 1
                cache[(r0, c0)] = (key, got)
                pieces.extend(got)
        self._cache = cache
        self.pieces = pieces
        return pieces
