"""The simulated obstacle sensor: a 3 m range and an 80° field of view around the heading.

Every cell whose centre lies within the range and inside the field of view is observed
and takes its true occupancy; what differs from the known map is returned as a delta
(flat cells, values), the same shape of message a real mapper would send.

No occlusion: a cell behind an obstacle is seen too. The benchmark measures the planner,
and without occlusion what is revealed is a function of the pose alone — the same for
every backend, mode and resolution, and O(cells in range) per step, which stays cheap at
2000 x 2000 where ray casting each cell would cost more than the planning it feeds. The
user still meets each obstacle before reaching it, which is what the walk needs. A stereo
camera does not see through boxes; a deployment gets its deltas from the real mapper.
"""

from __future__ import annotations

import math

import numpy as np

from daemon.planning.grid import Cell


class Sensor:
    """Which cells a pose observes; the delta those observations make to a known map."""

    def __init__(self, range_cells: float, fov_deg: float = 80.0) -> None:
        if range_cells <= 0:
            raise ValueError("range_cells must be positive")
        if not 0 < fov_deg <= 360:
            raise ValueError("fov_deg must be in (0, 360]")
        self.range_cells = float(range_cells)
        self.fov_deg = float(fov_deg)
        reach = math.floor(self.range_cells)
        dr, dc = np.mgrid[-reach : reach + 1, -reach : reach + 1]
        inside = dr * dr + dc * dc <= self.range_cells**2
        self._dr = dr[inside].astype(np.int64)
        self._dc = dc[inside].astype(np.int64)
        # Bearing of each offset, 0 = east, counter-clockwise (row 0 is north, so y = -dr).
        self._bearing = np.arctan2(-self._dr, self._dc)
        self._own = (self._dr == 0) & (self._dc == 0)

    def visible(self, shape: tuple[int, int], cell: Cell, heading: float) -> np.ndarray:
        """Flat indices of the cells observed from ``cell`` facing ``heading`` (radians)."""
        if self.fov_deg >= 360:
            mask = np.ones(self._dr.shape, dtype=bool)
        else:
            off = (self._bearing - heading + math.pi) % (2 * math.pi) - math.pi
            mask = (np.abs(off) <= math.radians(self.fov_deg) / 2) | self._own
        h, w = shape
        rr = self._dr[mask] + cell[0]
        cc = self._dc[mask] + cell[1]
        keep = (rr >= 0) & (rr < h) & (cc >= 0) & (cc < w)
        return rr[keep] * w + cc[keep]

    def sense(
        self, true: np.ndarray, known: np.ndarray, cell: Cell, heading: float
    ) -> tuple[np.ndarray, np.ndarray]:
        """The delta ``(cells, values)`` that brings ``known`` in line with ``true`` in view."""
        seen = self.visible(true.shape, cell, heading)
        values = true.reshape(-1)[seen]
        changed = known.reshape(-1)[seen] != values
        return seen[changed], values[changed]
