"""From a grid path to the few points where the user must turn.

The planner's path is a chain of 8-connected cells: it zig-zags in 45° steps even across open
ground. A blind walker needs the points where the direction really changes, as the CCNY smart
cane does: an iterative end-point fit (Douglas–Peucker) keeps the cells that deviate from the
chord by more than a tolerance, and any-angle shortcuts (string pulling) drop every cell the
user can walk past in a straight line — a straight line is allowed only where its line of sight
over the inflated ``blocked`` map is free.

Coordinates here are continuous cell units: cell (r, c) covers [r, r+1) x [c, c+1), its centre
is (r + 0.5, c + 0.5). Row grows southwards, as in ``daemon/planning/grid.py``.

The heading to the next point is Ghoniem et al.'s eq. 6, θ = atan2(Δy, Δx), taken relative to
the user's own heading so the belt and the voice speak in the user's frame.
"""

from __future__ import annotations

import itertools
import math

import numba
import numpy as np


@numba.njit(cache=True, nogil=True)
def segment_free(blocked: np.ndarray, r0: float, c0: float, r1: float, c1: float) -> bool:
    """True when the segment (r0, c0)→(r1, c1) enters no blocked cell and stays on the map.

    Amanatides–Woo traversal of every cell the segment passes through. A segment that only
    touches a corner point (exact tie between the row and column crossings) steps diagonally:
    the planner allows diagonal moves without free corners (``grid.py``), and a line through a
    single point of a cell does not enter it.
    """
    return segment_clear(blocked, r0, c0, r1, c1, 0)


@numba.njit(cache=True, nogil=True)
def is_core(blocked: np.ndarray, r: int, c: int, depth: int) -> bool:
    """True when every cell within ``depth`` (Chebyshev) of (r, c) is blocked or off the map."""
    h, w = blocked.shape
    for rr in range(r - depth, r + depth + 1):
        for cc in range(c - depth, c + depth + 1):
            if 0 <= rr < h and 0 <= cc < w and not blocked[rr, cc]:
                return False
    return True


@numba.njit(cache=True, nogil=True)
def _first_crossing(cell: int, start: float, delta: float) -> tuple[float, float]:
    """Along one axis of a segment: the fraction of it where it first leaves ``cell``, and
    the fraction between crossings (never, for a segment parallel to the other axis)."""
    if delta == 0.0:
        return 1e30, 1e30
    edge = (cell + 1.0 if delta > 0 else float(cell)) - start
    return edge / delta, abs(1.0 / delta)


@numba.njit(cache=True, nogil=True)
def segment_clear(
    blocked: np.ndarray, r0: float, c0: float, r1: float, c1: float, depth: int
) -> bool:
    """``segment_free`` that may cut the outer ``depth`` cells of the inflated margin.

    Only blocked cells whose whole (2·depth+1)² neighbourhood is blocked stop the segment.
    An occupied cell lies at least the user's radius inside the margin, so with ``depth``
    below radius/√2 it always stops the segment: the line may shave the margin, never reach
    an obstacle. ``depth`` 0 is ``segment_free``.
    """
    h, w = blocked.shape
    r, c = math.floor(r0), math.floor(c0)
    r_end, c_end = math.floor(r1), math.floor(c1)
    dr, dc = r1 - r0, c1 - c0
    step_r = 1 if dr > 0 else -1
    step_c = 1 if dc > 0 else -1
    t_max_r, t_delta_r = _first_crossing(r, r0, dr)
    t_max_c, t_delta_c = _first_crossing(c, c0, dc)
    n = abs(r_end - r) + abs(c_end - c) + 1
    for _ in range(n + 1):
        if r < 0 or r >= h or c < 0 or c >= w:
            return False
        if blocked[r, c] and (depth == 0 or is_core(blocked, r, c, depth)):
            return False
        if r == r_end and c == c_end:
            return True
        if abs(t_max_r - t_max_c) < 1e-9:
            if t_max_r > 1.0:
                return True
            r += step_r
            c += step_c
            t_max_r += t_delta_r
            t_max_c += t_delta_c
        elif t_max_r < t_max_c:
            if t_max_r > 1.0:
                return True
            r += step_r
            t_max_r += t_delta_r
        else:
            if t_max_c > 1.0:
                return True
            c += step_c
            t_max_c += t_delta_c
    return True


@numba.njit(cache=True, nogil=True)
def _string_pull(blocked: np.ndarray, path: np.ndarray, max_cells: float) -> np.ndarray:
    """Indices of the path cells kept by greedy any-angle shortcuts.

    From each anchor, walk forward along the path while the straight line from the anchor
    stays free (and no longer than ``max_cells``); the last visible cell becomes the next
    anchor. Stopping at the first hidden cell keeps the shortcut on the planner's side of
    every obstacle.
    """
    k = path.shape[0]
    keep = np.empty(k, dtype=np.int64)
    keep[0] = 0
    m = 1
    i = 0
    while i < k - 1:
        ri, ci = path[i, 0] + 0.5, path[i, 1] + 0.5
        j = i + 1
        while j + 1 < k:
            rj, cj = path[j + 1, 0] + 0.5, path[j + 1, 1] + 0.5
            if (rj - ri) ** 2 + (cj - ci) ** 2 > max_cells * max_cells:
                break
            if not segment_free(blocked, ri, ci, rj, cj):
                break
            j += 1
        keep[m] = j
        m += 1
        i = j
    return keep[:m]


@numba.njit(cache=True, nogil=True)
def _end_point_fit(pts: np.ndarray, tol: float) -> np.ndarray:
    """Mask of the points kept by the iterative end-point fit (an explicit stack, no recursion)."""
    n = pts.shape[0]
    keep = np.zeros(n, dtype=np.bool_)
    keep[0] = True
    keep[n - 1] = True
    stack = np.empty((2 * n, 2), dtype=np.int64)
    stack[0, 0], stack[0, 1] = 0, n - 1
    top = 1
    while top > 0:
        top -= 1
        i, j = stack[top, 0], stack[top, 1]
        if j <= i + 1:
            continue
        ar, ac = pts[i, 0], pts[i, 1]
        br, bc = pts[j, 0] - ar, pts[j, 1] - ac
        norm = math.hypot(br, bc)
        best, mid = -1.0, -1
        for k in range(i + 1, j):
            pr, pc = pts[k, 0] - ar, pts[k, 1] - ac
            d = math.hypot(pr, pc) if norm == 0.0 else abs(br * pc - bc * pr) / norm
            if d > best:
                best, mid = d, k
        if best > tol:
            keep[mid] = True
            stack[top, 0], stack[top, 1] = i, mid
            stack[top + 1, 0], stack[top + 1, 1] = mid, j
            top += 2
    return keep


def douglas_peucker(points: np.ndarray, tol: float) -> np.ndarray:
    """Iterative end-point fit: indices of the points kept at tolerance ``tol`` (same units)."""
    n = len(points)
    if n <= 2:
        return np.arange(n, dtype=np.int64)
    pts = np.ascontiguousarray(points, dtype=np.float64)
    return np.flatnonzero(_end_point_fit(pts, float(tol)))


def turning_points(
    path: np.ndarray,
    blocked: np.ndarray | None = None,
    tol_cells: float = 0.75,
    max_leg_cells: float = 1e9,
) -> np.ndarray:
    """The path's turning points, ``(m, 2) float64`` in continuous cell units, start included.

    With ``blocked``: any-angle shortcuts, then an end-point fit that may drop a further point
    only where the new straight leg is itself free. Without: the end-point fit alone.
    """
    path = np.asarray(path)
    if len(path) == 0:
        return np.empty((0, 2), dtype=np.float64)
    centres = path.astype(np.float64) + 0.5
    if blocked is None:
        return centres[douglas_peucker(centres, tol_cells)]
    blocked = np.ascontiguousarray(blocked, dtype=np.bool_)
    anchors = centres[_string_pull(blocked, path.astype(np.int64), float(max_leg_cells))]
    keep = douglas_peucker(anchors, tol_cells)
    # An end-point fit may merge legs into one chord that clips an obstacle or is longer than
    # a leg may be: put the dropped anchors back there.
    out = [anchors[keep[0]]]
    for a, b in itertools.pairwise(keep):
        pa, pb = anchors[a], anchors[b]
        too_long = math.hypot(pb[0] - pa[0], pb[1] - pa[1]) > max_leg_cells
        if b > a + 1 and (too_long or not segment_free(blocked, pa[0], pa[1], pb[0], pb[1])):
            out.extend(anchors[a + 1 : b])
        out.append(pb)
    return np.array(out, dtype=np.float64)


class KeptPoints:
    """``turning_points`` of the last call, given again for the same path and map.

    The points are a function of the path and ``blocked`` alone. Between two map deltas most
    steps are a pose's, on the same path and map, so they are the last step's points. The map
    is known the same by its array (held here, so its identity cannot pass to a new map's)
    and its ``version`` (moved on by every change in place: ``InflatedMap.version``).
    """

    def __init__(self) -> None:
        self._last: tuple[np.ndarray, int, float, np.ndarray, np.ndarray] | None = None

    def __call__(
        self, path: np.ndarray, blocked: np.ndarray | None, max_leg_cells: float,
        version: int | None,
    ) -> np.ndarray:  # fmt: skip
        """``turning_points(path, blocked, max_leg_cells=max_leg_cells)``; None for
        ``version`` (or no ``blocked``): worked out afresh, nothing kept."""
        if blocked is None or version is None:
            return turning_points(path, blocked, max_leg_cells=max_leg_cells)
        last = self._last
        if (
            last is not None
            and last[0] is blocked
            and last[1] == version
            and last[2] == max_leg_cells
            and np.array_equal(last[3], path)
        ):
            return last[4]
        pts = turning_points(path, blocked, max_leg_cells=max_leg_cells)
        pts.setflags(write=False)  # shared with the next steps: nobody may change it
        self._last = (blocked, version, max_leg_cells, np.array(path, copy=True), pts)
        return pts


def bearing(shape: tuple[int, int], src: np.ndarray, dst: np.ndarray) -> float:
    """World heading (rad, 0 = east, CCW) from ``src`` to ``dst`` (continuous cell units).

    Ghoniem et al. eq. 6: θ = atan2(y_next − y, x_next − x); rows grow southwards, so
    Δy = −Δrow.
    """
    del shape  # the angle does not depend on the map size; kept for a uniform call site
    return math.atan2(-(dst[0] - src[0]), dst[1] - src[1])


def relative_angle(world: float, heading: float) -> float:
    """``world`` seen from a user facing ``heading``: radians in (−π, π], positive = left."""
    a = (world - heading + math.pi) % (2.0 * math.pi) - math.pi
    return math.pi if a == -math.pi else a


def xy_to_continuous(shape: tuple[int, int], x: float, y: float, cell_m: float) -> np.ndarray:
    """Metres (x east, y north, origin south-west) → continuous cell units (row, col)."""
    return np.array([shape[0] - y / cell_m, x / cell_m], dtype=np.float64)
