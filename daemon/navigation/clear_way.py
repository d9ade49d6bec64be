"""The belt's direction keeps clear of known obstacles from where the user really stands.

The path, its turning points and the escape's lead are cells and cell centres; the user is a
point anywhere in a cell. A user pressed against a known box's face (a drift, or a step
stopped short by the box) and told to go to the next path point diagonally past the box's
corner clips that corner, although the line from the cell's centre only touches it. The
belt's hysteresis may turn the felt direction by up to 20° more (its snap to a motor), and
the walker reads the belt with its own error. In a camera walk this bumped one spot 16 times
in a row: 1 mm from the face, GUIDE at 200 ms, no STOP (a chest camera does not see a box
0.1 m away).

So, within ``NEAR_M`` of a known obstacle, the step checks the felt direction: its line from
the user's position over the next step, and the lines ``SPREAD_DEG`` either side of it (the
error of reading a four-motor belt), must enter no OCCUPIED cell. If they do, the belt
points to the nearest direction to the target that keeps clear (the exact bearing first,
then ever wider either side), and the hysteresis starts afresh from it. Where no direction
keeps clear, the pattern is left as it was: the STOP before contact is the camera's.
"""

from __future__ import annotations

import math

import numpy as np

from daemon.guidance.patterns import blend, decode
from daemon.guidance.turning_points import segment_free
from daemon.planning.grid import OCCUPIED
from protocol.messages import BeltPattern, PatternKind, Pose

NEAR_M = 0.3
"""Only a user this near a known obstacle (the user's radius) is checked: further away, the
inflated map the path keeps to already holds every line clear."""
STEP_MIN_M, STEP_MAX_M = 0.15, 0.3
"""The checked line runs to the target, but at least one short step (a walker beside an
obstacle is slowed to about 0.125 m by the fastest pulse) and at most the user's radius."""
SPREAD_DEG = 15.0
"""Half the cone that must stay clear: 1.7 sd of reading a direction off the belt (8°) and of a
step's veer (4°) together. (Belt walkers started 1-20 mm from a box's face below its corner,
30 walks: 71 bumps unchecked, 1 with a 10° cone, 0 with 15°, 60 walks.)"""
SEARCH_DEG = 5.0
"""Step of the search for a clear direction, either side of the bearing to the target."""


def _cell(shape: tuple[int, int], x: float, y: float, cell_m: float) -> tuple[int, int]:
    # Scalars: one-element arrays cost ~8 µs a call, and every guided step makes a few.
    return shape[0] - 1 - math.floor(y / cell_m), math.floor(x / cell_m)


def _near(occupancy: np.ndarray, x: float, y: float, cell_m: float) -> bool:
    h, w = occupancy.shape
    r0, c0 = _cell(occupancy.shape, x, y, cell_m)
    k = math.ceil(NEAR_M / cell_m) + 1
    window = occupancy[max(0, r0 - k) : min(h, r0 + k + 1), max(0, c0 - k) : min(w, c0 + k + 1)]
    return bool((window == OCCUPIED).any())


def clear_headings(
    occupancy: np.ndarray, x: float, y: float, headings: np.ndarray, reach_m: float, cell_m: float
) -> np.ndarray:
    """For each world heading (rad, 0 = east, CCW), whether the straight line of ``reach_m``
    from (x, y) metres enters no OCCUPIED cell and stays on the map (every cell it crosses,
    not samples: a line 1 mm from a face crosses a corner within a millimetre)."""
    h, w = occupancy.shape
    k = math.ceil(reach_m / cell_m) + 1
    r0, c0 = _cell(occupancy.shape, x, y, cell_m)
    rs, cs = max(0, r0 - k), max(0, c0 - k)
    re, ce = min(h, r0 + k + 1), min(w, c0 + k + 1)
    # Off the map counts as an obstacle: the window is padded with it where it is cut.
    window = np.ones((re - rs + 2, ce - cs + 2), np.bool_)
    window[1:-1, 1:-1] = occupancy[rs:re, cs:ce] == OCCUPIED
    if rs > 0:
        window[0, 1:-1] = occupancy[rs - 1, cs:ce] == OCCUPIED
    if re < h:
        window[-1, 1:-1] = occupancy[re, cs:ce] == OCCUPIED
    ur, uc = h - y / cell_m - rs + 1, x / cell_m - cs + 1  # continuous, in the window
    out = np.empty(len(headings), bool)
    for i, a in enumerate(headings):
        dr, dc = -math.sin(a) * reach_m / cell_m, math.cos(a) * reach_m / cell_m
        out[i] = segment_free(window, ur, uc, ur + dr, uc + dc)
    return out


def cone_clear(
    occupancy: np.ndarray, x: float, y: float, headings: np.ndarray, reach_m: float, cell_m: float
) -> np.ndarray:
    spread = math.radians(SPREAD_DEG)
    rays = np.concatenate([headings - spread, headings, headings + spread])
    ok = clear_headings(occupancy, x, y, rays, reach_m, cell_m).reshape(3, -1)
    return ok.all(axis=0)


def keep_clear(
    pattern: BeltPattern,
    pose: Pose,
    target_xy: tuple[float, float] | None,
    occupancy: np.ndarray,
    cell_m: float,
) -> BeltPattern | None:
    """A GUIDE that keeps clear of the known obstacles near ``pose``, or None when
    ``pattern`` does already (or nothing near, or no direction does)."""
    if pattern.kind != PatternKind.GUIDE or target_xy is None:
        return None
    x, y = pose.x, pose.y
    r, c = _cell(occupancy.shape, x, y, cell_m)
    h, w = occupancy.shape
    if not (0 <= r < h and 0 <= c < w) or occupancy[r, c] == OCCUPIED:
        return None  # a pose on an obstacle: the escape's lead out of it decides
    if not _near(occupancy, x, y, cell_m):
        return None
    felt = decode(pattern.motors)
    if felt is None:
        return None
    dx, dy = target_xy[0] - x, target_xy[1] - y
    reach = min(max(math.hypot(dx, dy), STEP_MIN_M), STEP_MAX_M)
    if cone_clear(occupancy, x, y, np.array([pose.heading - felt]), reach, cell_m)[0]:
        return None
    bearing = math.atan2(dy, dx)
    k = np.arange(1, int(180 / SEARCH_DEG) + 1)
    offsets = np.concatenate([[0.0], np.ravel(np.column_stack([k, -k]))]) * math.radians(SEARCH_DEG)
    ok = cone_clear(occupancy, x, y, bearing + offsets, reach, cell_m)
    if not ok.any():
        return None
    heading = bearing + offsets[int(np.argmax(ok))]
    cw = (pose.heading - heading) % (2.0 * math.pi)
    return pattern.model_copy(update={"motors": blend(cw)})
