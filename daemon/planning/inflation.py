"""Obstacle inflation by the user's radius, kept up to date as occupancy cells change.

Its own step, as in Nav2's costmap layers: the planners only ever see the inflated
``blocked`` map. Each occupied cell covers the disc of cells within the user's radius;
``cover[i]`` counts the discs covering cell i, so a cell is blocked while its count is
positive. A change of one occupancy cell adds or removes one disc — exact, with no
recomputation of the whole map — and reports only cells whose blocked state flipped.
"""

from __future__ import annotations

import math

import numpy as np

from .grid import CELL_M, OCCUPIED


def disc_offsets(radius_cells: int) -> tuple[np.ndarray, np.ndarray]:
    """Row and column offsets of every cell whose centre is within ``radius_cells``."""
    r = int(radius_cells)
    dr, dc = np.mgrid[-r : r + 1, -r : r + 1]
    inside = dr * dr + dc * dc <= r * r
    return dr[inside].astype(np.int64), dc[inside].astype(np.int64)


def radius_in_cells(radius_m: float, cell_m: float = CELL_M) -> int:
    return max(0, math.ceil(radius_m / cell_m - 1e-9))


class InflatedMap:
    """Occupancy (``uint8``) and its inflation (``blocked``), updated incrementally."""

    def __init__(self, occupancy: np.ndarray, radius_cells: int) -> None:
        self.shape: tuple[int, int] = (int(occupancy.shape[0]), int(occupancy.shape[1]))
        self.radius_cells = int(radius_cells)
        self._dr, self._dc = disc_offsets(self.radius_cells)
        self.occupancy = np.array(occupancy, dtype=np.uint8, copy=True)
        self.cover = np.zeros(self.shape, dtype=np.int32)
        rows, cols = np.nonzero(self.occupancy == OCCUPIED)
        self._add_discs(rows, cols, +1)
        self.blocked = self.cover > 0

    def _add_discs(self, rows: np.ndarray, cols: np.ndarray, sign: int) -> np.ndarray:
        """Add ``sign`` to the cover count of every disc cell; return their flat indices."""
        h, w = self.shape
        rr = (rows[:, None] + self._dr[None, :]).ravel()
        cc = (cols[:, None] + self._dc[None, :]).ravel()
        keep = (rr >= 0) & (rr < h) & (cc >= 0) & (cc < w)
        flat = rr[keep] * w + cc[keep]
        np.add.at(self.cover.reshape(-1), flat, sign)
        return flat

    def apply(self, cells: np.ndarray, values: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Set occupancy of flat ``cells`` to ``values``.

        Returns ``(flipped, blocked_now)``: the flat indices (sorted, unique) whose blocked
        state changed and their new blocked values — exactly what a planner's EDS
        update needs. Repeated cells in one call: the last value wins.
        """
        cells = np.asarray(cells, dtype=np.int64).ravel()
        values = np.asarray(values, dtype=np.uint8).ravel()
        if cells.shape != values.shape:
            raise ValueError("cells and values differ in length")
        if cells.size == 0:
            return np.empty(0, np.int64), np.empty(0, bool)
        if cells.min() < 0 or cells.max() >= self.shape[0] * self.shape[1]:
            raise IndexError("cell index outside the map")
        # Last write wins: keep each cell's final value only.
        rev_unique, rev_idx = np.unique(cells[::-1], return_index=True)
        final = values[::-1][rev_idx]
        occ = self.occupancy.reshape(-1)
        was = occ[rev_unique] == OCCUPIED
        now = final == OCCUPIED
        occ[rev_unique] = final
        w = self.shape[1]
        touched = []
        for mask, sign in ((now & ~was, +1), (was & ~now, -1)):
            sel = rev_unique[mask]
            if sel.size:
                touched.append(self._add_discs(sel // w, sel % w, sign))
        if not touched:
            return np.empty(0, np.int64), np.empty(0, bool)
        candidates = np.unique(np.concatenate(touched))
        blocked_flat = self.blocked.reshape(-1)
        new = self.cover.reshape(-1)[candidates] > 0
        flipped = candidates[new != blocked_flat[candidates]]
        blocked_flat[flipped] = ~blocked_flat[flipped]
        return flipped, blocked_flat[flipped].copy()
