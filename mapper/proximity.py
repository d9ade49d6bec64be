"""How near the nearest obstacles of the latest frame are: the belt's safety input.

Taken from the frame's own obstacle cells, never from the merged map: what matters for
contact is what the camera sees now, not what the planner knew. ``ahead_m`` is the
distance to the nearest obstacle cell inside the walking corridor (``corridor_m`` either
side of the heading, in front of the user); ``nearest_m``/``bearing`` that of the nearest
obstacle cell in any direction the camera sees, its bearing relative to the heading
(radians, counter-clockwise positive: left), which the belt turns into a motor.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numba import njit


@dataclass(frozen=True)
class Proximity:
    ahead_m: float | None
    nearest_m: float | None
    bearing: float | None
    stamp: float


def proximity_of(ahead: float, nearest: float, side: float, fwd: float,
                 stamp: float) -> Proximity:  # fmt: skip
    """The message from ``nearest_cells``' figures (NaN: none), on either backend: the
    bearing's atan2 is taken here, on the host, so the device's merge gives the same bits."""
    b = math.nan if math.isnan(nearest) else math.atan2(side, fwd)
    a, n = ahead, nearest  # only NaN is unequal to itself: no call per figure
    return Proximity(None if a != a else a, None if n != n else n, None if b != b else b, stamp)


@njit(cache=True, nogil=True)
def nearest_cells(occupied, r0, c0, map_rows, cell, x, y, ch, sh, corridor):
    """``Proximity``'s figures from this frame's obstacle cells (NaN: none): the nearest
    cell edge in the corridor ahead, the nearest in any direction, and that cell's side and
    forward offsets (its bearing is ``atan2(side, fwd)``). ``ch``, ``sh``: the heading's
    cosine and sine. ``kernels/merge_cells.cu`` does the same operations in the same order."""
    nearest, ahead = np.inf, np.inf
    near_side, near_fwd = np.nan, np.nan
    side_n = occupied.shape[0]
    for r in range(side_n):
        for c in range(side_n):
            if not occupied[r, c]:
                continue
            cx = (c + c0 + 0.5) * cell - x
            cy = (map_rows - (r + r0) - 0.5) * cell - y
            # Distance to the cell's nearest edge, not its centre: contact happens at the edge.
            dist = max(math.sqrt(cx * cx + cy * cy) - cell / 2, 0.0)
            fwd = cx * ch + cy * sh
            side = -cx * sh + cy * ch
            if dist < nearest:
                nearest, near_side, near_fwd = dist, side, fwd
            if fwd > -cell / 2 and abs(side) <= corridor + cell / 2:
                ahead = min(ahead, max(fwd - cell / 2, 0.0))
    if nearest == np.inf:
        nearest = np.nan
    if ahead == np.inf:
        ahead = np.nan
    return ahead, nearest, near_side, near_fwd
