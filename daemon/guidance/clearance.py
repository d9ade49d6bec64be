"""How far the way ahead is clear: the nearest blocked cell within ±60° of the user's heading,
which the GUIDE pattern's obstacle pulse feels (``patterns.PULSE_NEAR_M``)."""

from __future__ import annotations

import math

import numba
import numpy as np

from .patterns import PULSE_NEAR_M


def forward_clearance_m(
    blocked: np.ndarray | None, user: np.ndarray, heading: float, cell_m: float
) -> float | None:
    """Distance to the nearest blocked cell within ±60° of the heading (None if none near)."""
    if blocked is None:
        return None
    reach = math.ceil(PULSE_NEAR_M / cell_m) + 1
    d = _clearance_cells(blocked, float(user[0]), float(user[1]), heading, reach)
    return None if d < 0 else d * cell_m


@numba.njit(cache=True, nogil=True)
def _clearance_cells(
    blocked: np.ndarray, ur: float, uc: float, heading: float, reach: int
) -> float:
    """Distance (cells) to the near edge of the nearest blocked cell ahead (±60°) or touching
    the user; −1 when there is none within ``reach``."""
    h, w = blocked.shape
    r0, c0 = int(ur), int(uc)
    cos_limit = math.cos(math.radians(60.0))
    hx, hy = math.cos(heading), math.sin(heading)
    best = 1e30
    for r in range(max(0, r0 - reach), min(h, r0 + reach + 1)):
        for c in range(max(0, c0 - reach), min(w, c0 + reach + 1)):
            if not blocked[r, c]:
                continue
            dy = -((r + 0.5) - ur)
            dx = (c + 0.5) - uc
            dist = math.hypot(dx, dy)
            ahead = dist < 1.0 or (dx * hx + dy * hy) >= cos_limit * dist
            if ahead and dist < best:
                best = dist
    if best >= 1e30:
        return -1.0
    return max(0.0, best - 0.5)
