"""A path out of the inflation margin, for a user who stands inside it.

A newly seen obstacle can inflate over the user's own cell, or the user can drift off the
path into the margin; the planner has no path from a blocked cell. The way out leads in a
straight line to the nearby free cell whose total cost (octile distance to it plus its g)
is lowest, then follows the planner's path from there.
"""

from __future__ import annotations

import numpy as np

from .grid import DIAGONAL, INF, STRAIGHT, Cell
from .interface import Planner


def escape_path(
    planner: Planner, blocked: np.ndarray, cell: Cell, reach: int
) -> tuple[np.ndarray, int]:
    """``(path, cost)`` from a blocked ``cell`` within ``reach`` cells; empty and INF if none."""
    h, w = blocked.shape
    r0, c0 = cell
    rs, re = max(0, r0 - reach), min(h, r0 + reach + 1)
    cs, ce = max(0, c0 - reach), min(w, c0 + reach + 1)
    g = planner.costs()[rs:re, cs:ce].astype(np.int64)
    dr = np.abs(np.arange(rs, re) - r0)[:, None]
    dc = np.abs(np.arange(cs, ce) - c0)[None, :]
    # Octile distance in the planner's 10/14 units.
    out_cost = STRAIGHT * np.maximum(dr, dc) + (DIAGONAL - STRAIGHT) * np.minimum(dr, dc)
    total = np.where(blocked[rs:re, cs:ce] | (g >= INF), INF, g + out_cost)
    k = int(np.argmin(total))
    if total.flat[k] >= INF:
        return np.empty((0, 2), np.int32), int(INF)
    exit_cell = (rs + k // (ce - cs), cs + k % (ce - cs))
    n = max(abs(exit_cell[0] - r0), abs(exit_cell[1] - c0))
    t = np.linspace(0.0, 1.0, n + 1)[:-1]
    lead = np.stack(
        [np.rint(r0 + t * (exit_cell[0] - r0)), np.rint(c0 + t * (exit_cell[1] - c0))], axis=1
    ).astype(np.int32)
    return np.vstack([lead, planner.path(exit_cell)]), int(total.flat[k])
