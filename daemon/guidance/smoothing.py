"""Rubber-band smoothing (Hong & DeSouza) and the two metrics they judge a path by.

The grid path is a band of points, one per cell. Each iteration every inner point feels
- tension, pulling it towards the midpoint of its two neighbours (the band contracts, which
  shortens it and spreads the grid's 45° corners into gentle bends), and
- the push of obstacles within ``influence_cells``, growing as the point gets closer, which
  keeps the band off the obstacles it would otherwise be pulled onto.
A move is kept only if the point stays in a free cell and both segments to its neighbours stay
free (``segment_free`` over the inflated map); otherwise the point stays where it was. The band
therefore never cuts a blocked cell, at any iteration.

Metrics (their Table I and Figure 6): path length, and the histogram of turning angles — the
angle between consecutive segments at every vertex.

One smoothing model per planner (``SMOOTHING``, ``smooth_path``): the ``harmonic`` planner's
path is smoothed by the paper's own band (``daemon.planning.harmonic.rubber_band``: tension
plus the harmonic force ``F = 1/(1 − u(x̂)) − 1/(1 − u(x_i))``, read from that planner's
field); every other planner's by the band above (tension plus the push of nearby obstacles),
which needs no field. Guidance smooths only when asked (``Guidance(smooth=True)``), with the
model of the planner the navigator's route holds (``planner_band``): the harmonic planner's
``band`` (on the GPU where its field is, one thread per point as the paper's Figure 4), any
other planner's the band above.
"""

from __future__ import annotations

import math
from collections.abc import Callable

import numba
import numpy as np

from .turning_points import segment_free


@numba.njit(cache=True, nogil=True)
def _repulsion(blocked: np.ndarray, pts: np.ndarray, radius: float) -> np.ndarray:
    """Push of the blocked cells within ``radius`` on each point: the sum over those cells of
    (1 − d/radius)² along the way out, divided by the disc's area. Summing over every cell,
    not taking the nearest, makes the push a smooth field, like the gradient of a potential,
    so neighbouring points are not pushed in different directions."""
    h, w = blocked.shape
    out = np.zeros_like(pts)
    reach = math.ceil(radius)
    area = math.pi * radius * radius
    for i in range(pts.shape[0]):
        pr, pc = pts[i, 0], pts[i, 1]
        r0, c0 = math.floor(pr), math.floor(pc)
        fr, fc = 0.0, 0.0
        for r in range(max(0, r0 - reach), min(h, r0 + reach + 1)):
            for c in range(max(0, c0 - reach), min(w, c0 + reach + 1)):
                if blocked[r, c]:
                    dr, dc = pr - (r + 0.5), pc - (c + 0.5)
                    d = math.hypot(dr, dc)
                    if 0.0 < d < radius:
                        f = (1.0 - d / radius) ** 2
                        fr += f * dr / d
                        fc += f * dc / d
        out[i, 0] = fr / area
        out[i, 1] = fc / area
    return out


@numba.njit(cache=True, nogil=True)
def _keep_valid(blocked: np.ndarray, old: np.ndarray, new: np.ndarray) -> int:
    """Revert (in ``new``) every moved point whose cell or segments are blocked; count reverts."""
    k = new.shape[0]
    reverted = 0
    changed = True
    while changed:
        changed = False
        for i in range(1, k - 1):
            if new[i, 0] == old[i, 0] and new[i, 1] == old[i, 1]:
                continue
            r, c = math.floor(new[i, 0]), math.floor(new[i, 1])
            ok = 0 <= r < blocked.shape[0] and 0 <= c < blocked.shape[1] and not blocked[r, c]
            ok = ok and segment_free(blocked, new[i - 1, 0], new[i - 1, 1], new[i, 0], new[i, 1])
            ok = ok and segment_free(blocked, new[i, 0], new[i, 1], new[i + 1, 0], new[i + 1, 1])
            if not ok:
                new[i, 0], new[i, 1] = old[i, 0], old[i, 1]
                reverted += 1
                changed = True
    return reverted


SPACING_M = 0.10
"""One band point per 10 cm whatever the cell size: on finer grids the band would otherwise
need quadratically more iterations for the same straightening."""


@numba.njit(cache=True, nogil=True)
def _spaced(pts: np.ndarray, blocked: np.ndarray, every: int) -> np.ndarray:
    """Every ``every``-th point, keeping an intermediate one wherever the chord is not free."""
    n = pts.shape[0]
    keep = np.empty(n, dtype=np.int64)
    keep[0] = 0
    m, i = 1, 0
    while i < n - 1:
        j = min(i + max(1, every), n - 1)
        if not segment_free(blocked, pts[i, 0], pts[i, 1], pts[j, 0], pts[j, 1]):
            j = i + 1
        keep[m] = j
        m += 1
        i = j
    return pts[keep[:m]]


def rubber_band(
    path: np.ndarray,
    blocked: np.ndarray,
    *,
    cell_m: float = 0.10,
    iterations: int = 150,
    tension: float = 0.5,
    repulsion: float = 1.0,
    influence_m: float = 0.3,
    tol: float = 1e-3,
) -> np.ndarray:
    """The smoothed band, ``(k, 2) float64`` in continuous cell units (centre = cell + 0.5).

    Ends stay fixed. Stops early when no point moves more than ``tol`` cells. The defaults
    were chosen on the courtyard (``guidebelt walks --smoothing-plot``): strong enough a push
    to keep the band from zig-zagging along inflated edges, weak enough that it stays shorter
    than the grid path.
    """
    influence_cells = max(1.0, influence_m / cell_m)
    blocked = np.ascontiguousarray(blocked, dtype=np.bool_)
    pts = _spaced(np.asarray(path, dtype=np.float64) + 0.5, blocked, round(SPACING_M / cell_m))
    if len(pts) <= 2:
        return pts
    for _ in range(iterations):
        old = pts.copy()
        mid = 0.5 * (old[:-2] + old[2:])
        push = _repulsion(blocked, old[1:-1], influence_cells)
        pts[1:-1] = old[1:-1] + tension * (mid - old[1:-1]) + repulsion * push
        _keep_valid(blocked, old, pts)
        if float(np.abs(pts - old).max()) < tol:
            break
    return pts


def path_length(points: np.ndarray, cell_m: float = 1.0) -> float:
    """Polyline length (in metres when ``cell_m`` is the cell size)."""
    if len(points) < 2:
        return 0.0
    d = np.diff(np.asarray(points, dtype=np.float64), axis=0)
    return float(np.hypot(d[:, 0], d[:, 1]).sum()) * cell_m


def turning_angles(points: np.ndarray) -> np.ndarray:
    """Angle (degrees, 0..180) between consecutive segments at every inner vertex.

    Zero-length segments (repeated points) are dropped first.
    """
    pts = np.asarray(points, dtype=np.float64)
    if len(pts) < 3:
        return np.empty(0)
    d = np.diff(pts, axis=0)
    d = d[np.hypot(d[:, 0], d[:, 1]) > 1e-9]
    if len(d) < 2:
        return np.empty(0)
    a = np.arctan2(d[:, 0], d[:, 1])
    turn = (np.diff(a) + math.pi) % (2 * math.pi) - math.pi
    return np.degrees(np.abs(turn))


def turning_histogram(points: np.ndarray, bins: np.ndarray | None = None) -> np.ndarray:
    """Counts of turning angles in ``bins`` (default 0, 5, 10, …, 90, 180 degrees)."""
    if bins is None:
        bins = np.append(np.arange(0, 95, 5), 180)
    counts, _ = np.histogram(turning_angles(points), bins=bins)
    return counts


SMOOTHING = {"harmonic": "harmonic band (Hong & DeSouza eq. (2), the planner's field)"}
"""The smoothing model of each planner; any planner not named here: the repulsion band."""
DEFAULT_SMOOTHING = "repulsion band (tension + obstacle push)"


def smoothing_model(planner: str) -> str:
    return SMOOTHING.get(planner, DEFAULT_SMOOTHING)


def planner_band(planner: object) -> Callable[[np.ndarray, np.ndarray], np.ndarray] | None:
    """The planner's own smoothing model, ``band(path, blocked)``, where it has one (the
    harmonic planner's, read from its field); None: the repulsion band."""
    band = getattr(planner, "band", None)
    return band if callable(band) else None


def smooth_path(
    planner: str, path: np.ndarray, blocked: np.ndarray, cell_m: float, field: np.ndarray | None
) -> np.ndarray:
    """``path`` smoothed by ``planner``'s model (continuous cell units). The harmonic band
    needs the planner's ``field()`` (``w``); without it the repulsion band is used."""
    if planner == "harmonic" and field is not None:
        from daemon.planning.harmonic.rubber_band import rubber_band as harmonic_band

        return harmonic_band(path, field, blocked)
    return rubber_band(path, blocked, cell_m=cell_m)
