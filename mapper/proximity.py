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

from .binning import Window


@dataclass(frozen=True)
class Proximity:
    ahead_m: float | None
    nearest_m: float | None
    bearing: float | None
    stamp: float


def nearest_obstacles(occupied: np.ndarray, win: Window, x: float, y: float, heading: float,
                      corridor_m: float, stamp: float) -> Proximity:  # fmt: skip
    rr, cc = np.nonzero(occupied)
    if rr.size == 0:
        return Proximity(None, None, None, stamp)
    cell = win.cell_m
    cx = (cc + win.c0 + 0.5) * cell - x
    cy = (win.map_rows - (rr + win.r0) - 0.5) * cell - y
    # Distance to the cell's nearest edge, not its centre: contact happens at the edge.
    dist = np.maximum(np.hypot(cx, cy) - cell / 2, 0.0)
    fwd = cx * math.cos(heading) + cy * math.sin(heading)
    side = -cx * math.sin(heading) + cy * math.cos(heading)
    i = int(np.argmin(dist))
    nearest, bearing = float(dist[i]), math.atan2(side[i], fwd[i])
    lane = (fwd > -cell / 2) & (np.abs(side) <= corridor_m + cell / 2)
    ahead = float(np.maximum(fwd[lane] - cell / 2, 0.0).min()) if lane.any() else None
    return Proximity(ahead, nearest, bearing, stamp)
