"""What the user is told when the route changes under them, or they leave it.

The planner answers from the user's cell at every step, so the path always starts at the
user; what matters to the user is whether the way *ahead* changed. ``RouteWatch`` keeps the
route of the last step and compares:

- **Off route**: the user stands more than ``off_route_m`` from every cell of the last route
  (drift, a wrong turn): said once per excursion, until the user is back within half of it.
- **New route**: the user is on the last route, but the new one leaves it: some point of the
  new route within ``ahead_m`` of the user lies more than ``material_m`` from every cell of
  the last route (a newly seen obstacle closed the way, a door opened). A new route that only
  straightens a corner of the old one stays within ``material_m`` and is not announced.

Both are said at once, with the new direction (``guide.py``), and the belt shows the REROUTE
pattern for that step. Points are compared every ``SAMPLE_M`` so the cost does not grow with
the map's resolution.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Literal

import numpy as np
from numba import njit

SAMPLE_M = 0.1
"""Spacing of the route points compared (a 5 mm grid's route would be 20× as long)."""

Change = Literal["off_route", "new_route"]


@dataclass(frozen=True)
class RouteWatchSettings:
    ahead_m: float = 3.0
    material_m: float = 1.0
    off_route_m: float = 1.0


def _sampled(path: np.ndarray, cell_m: float) -> np.ndarray:
    step = max(1, math.ceil(SAMPLE_M / cell_m))
    head = path[::step]
    if not (len(path) and (len(path) - 1) % step):
        return head.astype(np.float64)
    # The route's end as well, written in place (``vstack`` cost more than the sampling).
    pts = np.empty((len(head) + 1, 2), np.float64)
    pts[:-1] = head
    pts[-1] = path[-1]
    return pts


@njit(cache=True, nogil=True)
def _nearest_m(points: np.ndarray, route: np.ndarray, cell_m: float) -> np.ndarray:
    """For each point, the distance (metres) to the nearest route point. Compiled: on the
    small arrays of one step numpy's per-call overhead was most of the daemon's step."""
    out = np.empty(points.shape[0])
    for i in range(points.shape[0]):
        best = np.inf
        for j in range(route.shape[0]):
            dr, dc = points[i, 0] - route[j, 0], points[i, 1] - route[j, 1]
            best = min(best, dr * dr + dc * dc)
        out[i] = np.sqrt(best) * cell_m
    return out


class RouteWatch:
    def __init__(self, settings: RouteWatchSettings | None = None) -> None:
        self.s = settings or RouteWatchSettings()
        self.reset()

    def reset(self) -> None:
        """A new goal, or after an event: nothing to compare with."""
        self._last: np.ndarray | None = None
        self._off = False
        self._checked: tuple[np.ndarray, float, np.ndarray] | None = None
        """The path ``check`` sampled this step, for ``keep`` of the same path after it."""

    def keep(self, path: np.ndarray, cell_m: float) -> None:
        """``path`` is the route the user was guided on this step (not one seen while the user
        was told to wait: the route they follow is still the last one)."""
        checked, self._checked = self._checked, None
        if checked is not None and checked[0] is path and checked[1] == cell_m:
            self._last = checked[2]
        else:
            self._last = _sampled(path, cell_m)

    def check(self, path: np.ndarray, cell_m: float) -> Change | None:
        """Compare ``path`` ((k, 2) cells from the user's cell) with the last route kept."""
        self._checked = None
        last = self._last
        if last is None or len(last) == 0 or len(path) == 0:
            return None
        user = path[:1].astype(np.float64)
        away = float(_nearest_m(user, last, cell_m)[0])
        if self._off:
            if away <= 0.5 * self.s.off_route_m:
                self._off = False
            return None  # one warning per excursion; the route from here is what counts
        if away > self.s.off_route_m:
            self._off = True
            return "off_route"
        sampled = _sampled(path, cell_m)
        # Kept for ``keep`` in the same step only: a path array may be refilled in place later.
        self._checked = (path, cell_m, sampled)
        ahead = sampled[: max(1, math.ceil(self.s.ahead_m / SAMPLE_M)) + 1]
        if float(_nearest_m(ahead, last, cell_m).max()) > self.s.material_m:
            return "new_route"
        return None
