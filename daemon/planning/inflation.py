"""Obstacle inflation by the user's radius, kept up to date as occupancy cells change.

Its own step, as in Nav2's costmap layers: the planners only ever see the inflated
``blocked`` map. Each occupied cell covers the disc of cells within the user's radius;
``cover[i]`` counts the discs covering cell i, so a cell is blocked while its count is
positive. A change of one occupancy cell adds or removes one disc — exact, with no
recomputation of the whole map — and reports only cells whose blocked state flipped.

The initial counts come from row-window sums (``disc_cover``): O(r·h·w) with no per-cell
discs, so a 2000 x 2000 map with a 60-cell radius stays cheap. The incremental stamping is
compiled with numba: a 3 m sensor sweep on a fine grid changes thousands of cells, each
stamping hundreds of disc cells, which ``np.add.at`` does an order of magnitude slower.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from .grid import CELL_M, OCCUPIED


def disc_offsets(radius_cells: int) -> tuple[np.ndarray, np.ndarray]:
    """Row and column offsets of every cell whose centre is within ``radius_cells``."""
    r = int(radius_cells)
    dr, dc = np.mgrid[-r : r + 1, -r : r + 1]
    inside = dr * dr + dc * dc <= r * r
    return dr[inside].astype(np.int64), dc[inside].astype(np.int64)


def radius_in_cells(radius_m: float, cell_m: float = CELL_M) -> int:
    return max(0, math.ceil(radius_m / cell_m - 1e-9))


def _disc_rows(occupied: np.ndarray, radius_cells: int, combine, out: np.ndarray) -> np.ndarray:
    """Fold, for every disc row ``dr``, the window sums of ``occupied`` shifted by ``dr``.

    The disc's row ``dr`` spans ``|dc| <= isqrt(r² - dr²)``: a window over a cumulative row
    count. ``combine(dst, src)`` adds (counts) or ors (dilation) into ``out``.
    """
    occ = np.asarray(occupied, dtype=bool)
    h, w = occ.shape
    r = int(radius_cells)
    cs = np.zeros((h, w + 1), dtype=np.int32)
    np.cumsum(occ, axis=1, out=cs[:, 1:])
    cols = np.arange(w)
    windows: dict[int, np.ndarray] = {}
    for dr in range(-min(r, h - 1), min(r, h - 1) + 1):  # a shift past the map adds nothing
        half = math.isqrt(r * r - dr * dr)
        if half not in windows:
            lo = np.clip(cols - half, 0, w)
            hi = np.clip(cols + half + 1, 0, w)
            windows[half] = cs[:, hi] - cs[:, lo]
        win = windows[half]
        if dr >= 0:
            combine(out[: h - dr], win[dr:])
        else:
            combine(out[-dr:], win[: h + dr])
    return out


def disc_cover(occupied: np.ndarray, radius_cells: int) -> np.ndarray:
    """``int32`` count of the radius discs of ``occupied`` cells covering each cell."""
    out = np.zeros(np.shape(occupied), dtype=np.int32)

    def _add(dst: np.ndarray, src: np.ndarray) -> None:
        dst += src

    return _disc_rows(occupied, radius_cells, _add, out)


def dilate(occupied: np.ndarray, radius_cells: int) -> np.ndarray:
    """Cells within ``radius_cells`` of an occupied cell: exactly ``InflatedMap.blocked``."""
    out = np.zeros(np.shape(occupied), dtype=bool)

    def _or(dst: np.ndarray, src: np.ndarray) -> None:
        dst |= src > 0

    return _disc_rows(occupied, radius_cells, _or, out)


@njit(cache=True, nogil=True)
def _stamp(cover, blocked, seen, epoch, w, cells, signs, dr, dc, touched):  # pragma: no cover
    """Add ``signs[i]`` over the disc of each cell; return the flat cells whose state flipped.

    ``seen`` (per cell, the epoch that last listed it) keeps ``touched`` free of repeats.
    """
    h = cover.shape[0] // w
    nt = 0
    for i in range(cells.shape[0]):
        r0 = cells[i] // w
        c0 = cells[i] % w
        for k in range(dr.shape[0]):
            r = r0 + dr[k]
            c = c0 + dc[k]
            if r < 0 or r >= h or c < 0 or c >= w:
                continue
            v = r * w + c
            cover[v] += signs[i]
            if seen[v] != epoch:
                seen[v] = epoch
                touched[nt] = v
                nt += 1
    nf = 0
    for j in range(nt):
        v = touched[j]
        now = cover[v] > 0
        if now != blocked[v]:
            blocked[v] = now
            touched[nf] = v
            nf += 1
    return nf


class InflatedMap:
    """Occupancy (``uint8``) and its inflation (``blocked``), updated incrementally."""

    def __init__(self, occupancy: np.ndarray, radius_cells: int) -> None:
        self.shape: tuple[int, int] = (int(occupancy.shape[0]), int(occupancy.shape[1]))
        self.radius_cells = int(radius_cells)
        self._dr, self._dc = disc_offsets(self.radius_cells)
        self.occupancy = np.array(occupancy, dtype=np.uint8, copy=True)
        self.cover = disc_cover(self.occupancy == OCCUPIED, self.radius_cells)
        self.blocked = self.cover > 0
        self._seen = np.zeros(self.shape[0] * self.shape[1], dtype=np.int32)
        self._epoch = 0
        self.version = 0
        """Moved on by every change to ``blocked`` in place (``apply``, ``reinflate``): what is
        worked out from ``blocked`` alone may be kept while it and the array stay the same."""

    def reinflate(self, radius_cells: int) -> tuple[np.ndarray, np.ndarray]:
        """Inflate by another radius, in place (planners hold ``blocked`` itself).

        Returns ``(flipped, blocked_now)`` as ``apply`` does.
        """
        new = InflatedMap(self.occupancy, radius_cells)
        flat = self.blocked.reshape(-1)
        flipped = np.flatnonzero(new.blocked.reshape(-1) != flat).astype(np.int64)
        self.radius_cells = new.radius_cells
        self._dr, self._dc = new._dr, new._dc
        self.cover[...] = new.cover
        self.blocked[...] = new.blocked
        self.version += 1
        return flipped, flat[flipped].copy()

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
        occ = self.occupancy.reshape(-1)
        if np.unique(cells).size != cells.size:  # last write wins: keep each cell's final value
            rev_unique, rev_idx = np.unique(cells[::-1], return_index=True)
            cells, values = rev_unique, values[::-1][rev_idx]
        was = occ[cells] == OCCUPIED
        now = values == OCCUPIED
        occ[cells] = values
        moved = was != now
        if not moved.any():
            return np.empty(0, np.int64), np.empty(0, bool)
        stamp_cells = cells[moved]
        signs = np.where(now[moved], 1, -1).astype(np.int32)
        self._epoch += 1
        if self._epoch >= 2**31 - 1:
            self._seen[:] = 0
            self._epoch = 1
        # Every listed cell is distinct, so the map's size bounds the list.
        touched = np.empty(min(stamp_cells.size * self._dr.size, self._seen.size), np.int64)
        nf = _stamp(
            self.cover.reshape(-1), self.blocked.reshape(-1), self._seen, self._epoch,
            self.shape[1], stamp_cells, signs, self._dr, self._dc, touched,
        )  # fmt: skip
        flipped = np.sort(touched[:nf])
        if nf:
            self.version += 1
        return flipped, self.blocked.reshape(-1)[flipped].copy()
