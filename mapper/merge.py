"""One frame's evidence merged into the map, in one numba pass that holds no GIL.

What the frame says per cell of its window (``binning.Binned``) becomes the fused map: the
clearing rays (``binning.clear_rays``), the range-noise tails (``evidence._tails``), hits and
passes, the per-cell log-odds update of Thrun, Burgard & Fox (*Probabilistic Robotics*,
2005, ch. 9: l_t = l_{t-1} + log-odds of the inverse sensor model − l_0, l_0 = 0) clamped to
[l_min, l_max], the published value with its hysteresis, the obstacles forgotten out of
view, and the frame's proximity. The rules are ``occupancy_mapper``'s (its docstring says
them); here they run as loops over the window instead of a dozen numpy calls, each of which
held the GIL, so the floor fit's thread and the frame no longer take turns.

The map is written only at the very end of the call, once every change is known, so a frame
refused before it leaves the map as it was; the call itself cannot fail part way.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from .binning import clear_rays
from .evidence import _BEYOND_COS, _tails
from .proximity import nearest_cells

FREE, OCCUPIED, UNKNOWN = 0, 1, 2


@njit(cache=True, nogil=True)
def merge_frame(obst, floor, hit, far, cam_x, cam_y, cos_h, sin_h, r0, c0, map_rows, cell,
                occupancy, logodds, seen_at, fixed, stamp, forget_before,
                min_points, min_share, tail_share, l_hit, l_pass, l_occupied, l_free,
                l_min, l_max, corridor):  # fmt: skip
    """Merge one binned frame into ``occupancy``, ``logodds`` and ``seen_at`` (in place, at
    the end). ``forget_before`` (-inf: not this frame) also sends back to UNKNOWN every
    obstacle not fixed, not seen since then and not seen now. Returns the changed flat
    cells, their values and the proximity's (ahead, nearest, side, fwd), NaN where none
    (``proximity.nearest_cells``; ``cos_h``, ``sin_h``: the heading's)."""
    side = obst.shape[0]
    h, w = occupancy.shape
    free = clear_rays(hit, far, cam_x, cam_y, r0, c0, side, map_rows, cell, 0.5 * cell)
    inv = 1.0 / cell
    cam_row = map_rows - 1 - cam_y * inv + 0.5 - r0
    cam_col = cam_x * inv - 0.5 - c0
    tail = _tails(obst, cam_row, cam_col, tail_share, _BEYOND_COS)
    occupied = np.zeros((side, side), np.bool_)
    for r in range(side):
        for c in range(side):
            o = obst[r, c]
            occupied[r, c] = o >= min_points and o >= min_share * (o + floor[r, c])
    near = nearest_cells(occupied, r0, c0, map_rows, cell, cam_x, cam_y, cos_h, sin_h, corridor)
    # The map keeps float32 log-odds: the update is done in float32, as numpy did it.
    hit32, pass32 = np.float32(l_hit), np.float32(l_pass)
    occ32, free32 = np.float32(l_occupied), np.float32(l_free)
    lo32, hi32 = np.float32(l_min), np.float32(l_max)
    ra, rb = max(0, r0), min(h, r0 + side)
    ca, cb = max(0, c0), min(w, c0 + side)
    n = max(0, rb - ra) * max(0, cb - ca)
    cells = np.empty(n, np.int64)
    values = np.empty(n, np.uint8)
    seen = np.empty(n, np.int64)
    odds = np.empty(n, np.float32)
    where = np.empty(n, np.int64)
    k = ns = nw = 0
    for mr in range(ra, rb):
        for mc in range(ca, cb):
            r, c = mr - r0, mc - c0
            is_hit = occupied[r, c] and not tail[r, c]
            floor_seen = floor[r, c] >= min_points
            # Floor seen in a cell with nothing standing in it is free whatever the rays
            # say: each floor point's own line of sight reached it (over a low box, past
            # the side of a ray ended nearer). A tail whose floor is seen: its rays went on
            # through it, a pass.
            cleared = (obst[r, c] == 0 and (free[r, c] != 0 or floor_seen)) or (
                tail[r, c] and floor_seen
            )
            if not (is_hit or cleared):
                continue
            flat = mr * w + mc
            seen[ns] = flat
            ns += 1
            old = occupancy[mr, mc]
            # A ray grazing the corner of a mapped obstacle's cell is no proof it has gone:
            # a pass counts against it only where its floor is seen.
            passes = cleared and (old != OCCUPIED or floor_seen)
            v = logodds[mr, mc]
            if is_hit:
                v = v + hit32
            if passes:
                v = v + pass32
            v = min(max(v, lo32), hi32)
            odds[nw], where[nw] = v, flat
            nw += 1
            new = old
            if v >= occ32:
                new = OCCUPIED
            elif v <= free32:
                new = FREE
            if new != old:
                cells[k], values[k] = flat, new
                k += 1
    cells, values = cells[:k], values[:k]
    if forget_before > -np.inf:
        gone = np.zeros(h * w, np.bool_)
        flat_occ = occupancy.reshape(-1)
        flat_seen = seen_at.reshape(-1)
        flat_fixed = fixed.reshape(-1)
        for i in range(h * w):
            gone[i] = flat_occ[i] == OCCUPIED and not flat_fixed[i] and flat_seen[i] < forget_before
        for i in range(ns):
            gone[seen[i]] = False
        idx = np.flatnonzero(gone)
        if idx.size:
            cells = np.concatenate((cells, idx))
            values = np.concatenate((values, np.full(idx.size, UNKNOWN, np.uint8)))
    # Everything is known: only now does the map change.
    flat_lo = logodds.reshape(-1)
    for i in range(nw):
        flat_lo[where[i]] = odds[i]
    flat_occ = occupancy.reshape(-1)
    for i in range(cells.size):
        flat_occ[cells[i]] = values[i]
        if values[i] == UNKNOWN:
            flat_lo[cells[i]] = 0.0  # forgotten
    flat_seen = seen_at.reshape(-1)
    for i in range(ns):
        flat_seen[seen[i]] = stamp
    return cells, values, near[0], near[1], near[2], near[3]


HOST_PRESENT = 8
"""Where ``merge_params`` holds the host's count of the frame's valid pixels
(``merge_cells.cu``'s HOST_PRESENT, P[27 + 8]): -1, the device counts them, unless the binner
counts the original of a depth the device sees subsampled or cast."""


def merge_params(settings, cos_h: float, sin_h: float, cam_row: float, cam_col: float,
                 stamp: float, forget_before: float, need: float,
                 motion_ok: bool) -> list[float]:  # fmt: skip
    """What ``merge_frame`` takes beyond the pass's output, for the device's merge
    (``kernels/merge_cells.cu``'s P[27..46]): the frame's, then the mapper's settings;
    ``HOST_PRESENT`` is -1."""
    s = settings
    return [
        cos_h, sin_h, cam_row, cam_col, stamp, forget_before, need, float(motion_ok), -1.0,
        float(s.min_points), s.min_share, s.tail_share, s.l_hit, s.l_pass, s.l_occupied,
        s.l_free, s.l_min, s.l_max, s.corridor_m, _BEYOND_COS,
    ]  # fmt: skip
