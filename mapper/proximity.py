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


@njit(cache=True, nogil=True)
def nearest_cells(occupied, r0, c0, map_rows, cell, x, y, heading, corridor):
    """``Proximity``'s three figures from this frame's obstacle cells (NaN: none): the
    nearest cell edge in the corridor ahead, the nearest in any direction and its bearing."""
    ch, sh = math.cos(heading), math.sin(heading)
    nearest, bearing, ahead = np.inf, np.nan, np.inf
    side_n = occupied.shape[0]
    for r in range(side_n):
        for c in range(side_n):
            if not occupied[r, c]:
                continue
            cx = (c + c0 + 0.5) * cell - x
            cy = (map_rows - (r + r0) - 0.5) * cell - y
            # Distance to the cell's nearest edge, not its centre: contact happens at the edge.
            dist = max(math.hypot(cx, cy) - cell / 2, 0.0)
            fwd = cx * ch + cy * sh
            side = -cx * sh + cy * ch
            if dist < nearest:
                nearest, bearing = dist, math.atan2(side, fwd)
            if fwd > -cell / 2 and abs(side) <= corridor + cell / 2:
                ahead = min(ahead, max(fwd - cell / 2, 0.0))
    if nearest == np.inf:
        nearest = np.nan
    if ahead == np.inf:
        ahead = np.nan
    return ahead, nearest, bearing
