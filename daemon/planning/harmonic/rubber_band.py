"""Hong & DeSouza's rubber band (§IV, Figures 2–4): the harmonic path as an elastic line.

The path is a chain of points, one per path cell at the start (continuous cell units, centre
= cell + 0.5). Eq. (2) reads ``P_i ← P_i + δ·(x̂, ŷ)`` with ``(x̂, ŷ)`` the neighbour offset
(one of the 8, or none) where the forces on the point are smallest; here the forces are
judged where the point would go, ``x̂ = P_i + δ·offset``:

    ‖T_{i−1}(x̂) + T_{i+1}(x̂)‖ + F(x̂),   T_{i±1}(x̂) = P_{i±1} − x̂   (the tension),
    F(x̂) = 1/(1 − u(x̂)) − 1/(1 − u(x_i))                          (the harmonic force),

with ``u`` read between cell centres bilinearly (a potential constant over a cell pushes
nothing within it). All points move at once, from the last iteration's positions, as the
paper's per-point GPU kernel (Figure 4) does.

``1/(1 − u)`` is ``exp(w)``: it overflows past w ~ 709 and, far from the goal, dwarfs the
tension by hundreds of orders of magnitude. The force is therefore taken relative to the
point's own potential, ``F·(1 − u(x_i)) = exp(w(x̂) − w(x_i)) − 1``: the paper's force scaled
by a positive number per point, so its sign and its ordering of the candidates stay the
paper's, and it balances the tension in cell units everywhere. A move whose
new point is in a blocked cell, or whose segments to its neighbours cross one, is refused
(the point stays); so the band never cuts an obstacle, at any iteration.

Stops when no point moved (more than ``tol`` cells), or after ``iterations``. Moves are
whole steps of δ, so a band whose points trade places between two moves never stops early:
measured on the courtyard's paths, it ran all 200 iterations every time, shortening by ~1 %
after the first 20. A caller that bands every step (guidance) therefore runs a few
iterations per call from where its last band left each path cell (``warm_points``), as the
paper's band is a process that goes on while the path is followed.
"""

from __future__ import annotations

import math

import numba
import numpy as np

from .relax import BLOCKED_W


@numba.njit(cache=True, nogil=True)
def _free_line(blocked: np.ndarray, r0: float, c0: float, r1: float, c1: float) -> bool:
    """True when the segment stays on free cells (sampled every 0.1 cell, both ends in)."""
    h, w = blocked.shape
    n = max(1, math.ceil(10.0 * max(abs(r1 - r0), abs(c1 - c0))))
    for k in range(n + 1):
        t = k / n
        r = math.floor(r0 + t * (r1 - r0))
        c = math.floor(c0 + t * (c1 - c0))
        if r < 0 or r >= h or c < 0 or c >= w or blocked[r, c]:
            return False
    return True


@numba.njit(cache=True, nogil=True)
def _w_at(w: np.ndarray, r: float, c: float, cap: float) -> float:
    """``w`` between cell centres, bilinear; a blocked or outside corner counts ``cap``."""
    h, width = w.shape
    y, x = r - 0.5, c - 0.5
    r0, c0 = math.floor(y), math.floor(x)
    fy, fx = y - r0, x - c0
    total = 0.0
    for dr in range(2):
        for dc in range(2):
            rr, cc = r0 + dr, c0 + dc
            v = cap
            if 0 <= rr < h and 0 <= cc < width and w[rr, cc] < cap:
                v = w[rr, cc]
            total += (fy if dr else 1.0 - fy) * (fx if dc else 1.0 - fx) * v
    return total


@numba.njit(cache=True, nogil=True)
def band_iterations(
    pts: np.ndarray,
    w: np.ndarray,
    blocked: np.ndarray,
    delta: float,
    iterations: int,
    tol: float,
) -> int:
    """Move ``pts`` (``(k, 2)`` float64, in place) by the rubber band; returns iterations."""
    h, width = w.shape
    k = pts.shape[0]
    new = pts.copy()
    done = 0
    for _ in range(iterations):
        worst = 0.0
        for i in range(1, k - 1):
            pr, pc = pts[i, 0], pts[i, 1]
            # A corner that is blocked weighs as a potential well above the point's own.
            cap = 0.0
            for d in range(9):
                rr = min(h - 1, max(0, int(pr) + d // 3 - 1))
                cc = min(width - 1, max(0, int(pc) + d % 3 - 1))
                if w[rr, cc] < BLOCKED_W:
                    cap = max(cap, w[rr, cc])
            cap += 10.0
            wi = _w_at(w, pr, pc, cap)
            best_r, best_c, best = pr, pc, math.inf
            for d in range(9):
                xr, xc = pr + delta * (d // 3 - 1), pc + delta * (d % 3 - 1)
                r, c = math.floor(xr), math.floor(xc)
                if r < 0 or r >= h or c < 0 or c >= width or blocked[r, c]:
                    continue
                tr = pts[i - 1, 0] + pts[i + 1, 0] - 2.0 * xr
                tc = pts[i - 1, 1] + pts[i + 1, 1] - 2.0 * xc
                force = math.exp(min(_w_at(w, xr, xc, cap) - wi, 50.0)) - 1.0
                value = math.hypot(tr, tc) + force
                if value < best:
                    best, best_r, best_c = value, xr, xc
            ok = _free_line(blocked, pts[i - 1, 0], pts[i - 1, 1], best_r, best_c)
            ok = ok and _free_line(blocked, best_r, best_c, pts[i + 1, 0], pts[i + 1, 1])
            if ok:
                new[i, 0], new[i, 1] = best_r, best_c
                worst = max(worst, math.hypot(best_r - pr, best_c - pc))
            else:
                new[i, 0], new[i, 1] = pr, pc
        pts[:, :] = new
        done += 1
        if worst < tol:
            break
    return done


@numba.njit(cache=True, nogil=True)
def _unbend(pts: np.ndarray, centres: np.ndarray, blocked: np.ndarray) -> int:
    """Put back on its cell centre each point of a segment that crosses a blocked cell, until
    none does (a band warm-started from two earlier bands can join up across an obstacle).
    Centre to centre of neighbouring path cells is the grid path itself. Returns resets."""
    resets = 0
    changed = True
    while changed:
        changed = False
        for i in range(pts.shape[0] - 1):
            a_moved = pts[i, 0] != centres[i, 0] or pts[i, 1] != centres[i, 1]
            b_moved = pts[i + 1, 0] != centres[i + 1, 0] or pts[i + 1, 1] != centres[i + 1, 1]
            if not (a_moved or b_moved):
                continue
            if not _free_line(blocked, pts[i, 0], pts[i, 1], pts[i + 1, 0], pts[i + 1, 1]):
                pts[i, :] = centres[i, :]
                pts[i + 1, :] = centres[i + 1, :]
                resets += 1
                changed = True
    return resets


def warm_points(path: np.ndarray, blocked: np.ndarray, last: tuple | None) -> np.ndarray:
    """The band's first points: each path cell's centre, or where the ``last`` band (``(flat
    cells sorted, their points)``) had left that cell's point; the ends on their centres."""
    centres = np.asarray(path, dtype=np.float64) + 0.5
    pts = centres.copy()
    if last is not None and len(path) > 2:
        cells, points = last
        flat = path[:, 0].astype(np.int64) * blocked.shape[1] + path[:, 1]
        k = np.searchsorted(cells, flat).clip(0, len(cells) - 1)
        hit = cells[k] == flat
        hit[0] = hit[-1] = False
        pts[hit] = points[k[hit]]
        _unbend(pts, centres, np.ascontiguousarray(blocked, dtype=np.bool_))
    return pts


def band_memory(path: np.ndarray, band: np.ndarray, width: int) -> tuple:
    """What ``warm_points`` starts the next band from: the path's flat cells, sorted, and
    their band points."""
    flat = path[:, 0].astype(np.int64) * width + path[:, 1]
    order = np.argsort(flat)
    return flat[order], band[order]


def rubber_band(
    path: np.ndarray,
    w: np.ndarray,
    blocked: np.ndarray,
    *,
    delta: float = 0.25,
    iterations: int = 200,
    tol: float = 1e-3,
    start: np.ndarray | None = None,
) -> np.ndarray:
    """The band of ``path`` (``(k, 2)`` cells) in the field ``w`` (the planner's ``field()``),
    ``(k, 2) float64`` in continuous cell units; the ends stay fixed. ``delta``: the paper's
    step (0 < δ < 1). ``start``: the first points (``warm_points``; default the centres)."""
    pts = np.asarray(path, dtype=np.float64) + 0.5 if start is None else start.copy()
    if len(pts) > 2:
        band_iterations(pts, np.ascontiguousarray(w, dtype=np.float64),
                        np.ascontiguousarray(blocked, dtype=np.bool_), float(delta),
                        int(iterations), float(tol))  # fmt: skip
    return pts
