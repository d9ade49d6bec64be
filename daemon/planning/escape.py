"""A path out of the inflation margin, for a user who stands inside it.

A newly seen obstacle can inflate over the user's own cell, or the user can drift off the
path into the margin; the planner has no path from a blocked cell. The way out leads in a
straight line to the *nearest* free cell that has a path (ties: the lowest total cost) and
whose line crosses no occupied cell, then follows the planner's path from there. No such
cell within reach means no path: the user is told so rather than led through an obstacle.
A pose on an occupied cell (the estimate pinned onto a blob the sensor saw beside the user) is
led out of that obstacle the shortest way; before, every lead began on an occupied cell, no
exit was usable, and the user stood at NO_PATH for good.
An exit from which the planner gives no path (extended A*, which ranks exits by the exact
field but may miss a path) is passed over; the cost is the lead's plus the path's own.

Nearest, not cheapest overall: the cheapest exit can lie across the obstacle, and a straight
lead there walks the user into it (a walker that feels the belt bumped thousands of times
with the cheapest exit, never with the nearest).
"""

from __future__ import annotations

import numpy as np

from .grid import DIAGONAL, INF, OCCUPIED, STRAIGHT, Cell, path_cost
from .interface import GlobalPlanner

LEAVE_CELLS = 3
"""The most occupied cells a way out may begin with (0.3 m at 10 cm cells): an estimate deeper
in an obstacle than that is no user pinned beside it, and a longer lead would walk them through
it; then no way out is given (NO_PATH), as for any lead through an obstacle."""
LEAD_CLEAR_CELLS = 0.1
"""How near a lead's centre line may pass an occupied cell, once out of the run it starts in:
a tenth of a cell, so it never runs through the corner point two occupied cells share, nor
across or along the corner of one. The lead's own cells (one per step of the longer axis) missed
both: in a camera walk a lead went diagonally past the corner of the box the user stood beside,
then between two diagonal neighbours, and the walker bumped 16 times from one spot. Half a cell
was tried first: in seed 13's walk it emptied 83 of 1644 escapes that had a way out (5 %), and
the walks arrived less often; where in its cell the user really stands is the step's own check
(``daemon/navigation/clear_way.py``)."""
_SAMPLES_PER_CELL = 20


def _line(a: Cell, b: Cell) -> np.ndarray:
    """Cells from ``a`` towards ``b`` (``b`` excluded), one per step of the longer axis."""
    n = max(abs(b[0] - a[0]), abs(b[1] - a[1]))
    t = np.linspace(0.0, 1.0, n + 1)[:-1]
    return np.stack(
        [np.rint(a[0] + t * (b[0] - a[0])), np.rint(a[1] + t * (b[1] - a[1]))], axis=1
    ).astype(np.int32)


def _keeps_clear(occupancy: np.ndarray, a: np.ndarray, b: np.ndarray) -> bool:
    """True when the segment between the centres of cells ``a`` and ``b`` keeps at least
    ``LEAD_CLEAR_CELLS`` from every OCCUPIED cell (sampled every 1/20 of a cell)."""
    n = max(1, int(np.ceil(np.hypot(*(b - a)) * _SAMPLES_PER_CELL)))
    t = np.linspace(0.0, 1.0, n + 1)[:, None]
    pts = a + 0.5 + t * (b - a).astype(np.float64)  # continuous cell units
    h, w = occupancy.shape
    base = np.floor(pts).astype(np.int64)
    for dr in (-1, 0, 1):
        for dc in (-1, 0, 1):
            r, c = base[:, 0] + dr, base[:, 1] + dc
            on = (r >= 0) & (r < h) & (c >= 0) & (c < w)
            occ = np.zeros(len(pts), bool)
            occ[on] = occupancy[r[on], c[on]] == OCCUPIED
            if not occ.any():
                continue
            # Distance from each point to the square [r, r+1) x [c, c+1).
            gr = np.maximum(np.maximum(r - pts[:, 0], pts[:, 0] - (r + 1)), 0.0)
            gc = np.maximum(np.maximum(c - pts[:, 1], pts[:, 1] - (c + 1)), 0.0)
            if (occ & (np.hypot(gr, gc) < LEAD_CLEAR_CELLS - 1e-6)).any():
                return False
    return True


def field_at(planner: GlobalPlanner, cells: np.ndarray) -> np.ndarray:
    """The planner's field (cost to the goal) at ``(k, 2)`` cells, read in one go where the
    planner can give it (a searching planner's window, an EDS/DSS planner's whole field),
    else cell by cell."""
    if len(cells) == 0:
        return np.empty(0, np.int64)
    within = getattr(planner, "costs_within", None)
    if within is not None:  # a searching planner: the window the cells span
        rs, cs = cells.min(axis=0)
        re, ce = cells.max(axis=0) + 1
        g = within(int(rs), int(re), int(cs), int(ce))
        return g[cells[:, 0] - rs, cells[:, 1] - cs].astype(np.int64)
    costs = getattr(planner, "costs", None)
    if costs is not None:
        return costs()[cells[:, 0], cells[:, 1]].astype(np.int64)
    return np.array([planner.cost_at((int(r), int(c))) for r, c in cells], np.int64)


def escape_path(
    planner: GlobalPlanner, blocked: np.ndarray, occupancy: np.ndarray, cell: Cell, reach: int
) -> tuple[np.ndarray, int]:
    """``(path, cost)`` from a blocked ``cell`` within ``reach`` cells; empty and INF if none."""
    h, w = blocked.shape
    r0, c0 = cell
    rs, re = max(0, r0 - reach), min(h, r0 + reach + 1)
    cs, ce = max(0, c0 - reach), min(w, c0 + reach + 1)
    within = getattr(planner, "costs_within", None)  # a searching planner (A*): the window
    costs = getattr(planner, "costs", None)  # an EDS/DSS planner's whole field: one copy
    if within is not None:
        g = within(rs, re, cs, ce).astype(np.int64)
    elif costs is not None:
        g = costs()[rs:re, cs:ce].astype(np.int64)
    else:
        g = np.array([[planner.cost_at((r, c)) for c in range(cs, ce)] for r in range(rs, re)])
    dr = np.abs(np.arange(rs, re) - r0)[:, None]
    dc = np.abs(np.arange(cs, ce) - c0)[None, :]
    # Octile distance in the planner's 10/14 units.
    out_cost = STRAIGHT * np.maximum(dr, dc) + (DIAGONAL - STRAIGHT) * np.minimum(dr, dc)
    usable = ~blocked[rs:re, cs:ce] & (g < INF)
    total = np.where(usable, g + out_cost, INF)
    # Nearest first (squared distance), then the lowest total cost.
    key = (dr * dr + dc * dc) * (4 * int(INF)) + total
    for k in np.flatnonzero(usable.ravel())[np.argsort(key.ravel()[usable.ravel()], kind="stable")]:
        exit_cell = (rs + int(k) // (ce - cs), cs + int(k) % (ce - cs))
        lead = _line(cell, exit_cell)
        hit = occupancy[lead[:, 0], lead[:, 1]] == OCCUPIED
        # An estimate on an occupied cell (an uncertain pose pinned beside a blob the sensor
        # has just seen) is no user inside the obstacle: the way out may leave the occupied
        # run it starts in, but never enter another.
        leave = int(np.argmin(hit)) if not hit.all() else len(hit)
        if leave > LEAVE_CELLS or hit[leave:].any():
            continue  # the straight way there runs through an obstacle
        end = np.array(exit_cell)
        if not _keeps_clear(occupancy, lead[leave] if leave < len(lead) else end, end):
            continue  # it grazes an obstacle's corner, or squeezes between two
        tail = planner.path(exit_cell)
        if len(tail) == 0:
            continue  # a planner that may miss a path (extended A*) has none from there
        return np.vstack([lead, tail]), int(out_cost.flat[k]) + path_cost(tail)
    return np.empty((0, 2), np.int32), int(INF)
