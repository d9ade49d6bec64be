"""Out of a pocket along the user's own track, and the dead end remembered once left.

A camera sees no further than the first face, so a user can walk through a gap whose sides
were still unknown into a pocket the inflated map then closes: no planned path, and no
usable cell within the escape's reach. The cells the user just walked are known passable,
so the way out is the track walked backwards, up to the first cell from which the planner
has a path again (never across a cell the map holds OCCUPIED: the safety rule that no
direction leads into a known obstacle holds for the track too). The track keeps no loops:
a cell stood on again cuts the track back to that cell, so the way back is the shortest the
user has shown.

Once the user is out, the way they were led (every cell of it had no path: the pocket and
the gap too narrow once inflated) and the obstacles beside it, inflated, are kept blocked
for the planner as a *dead end*, until the goal changes: otherwise the pocket's walls,
forgotten once out of view, open the gap again and the route leads back in (the
forget-and-return back-and-forth). A dead end that leaves the user no path at all is
dropped (the map, not the memory, decides then). The belt meanwhile guides as ever, its
direction back along the track; the status says "dead end: back along your track".
"""

from __future__ import annotations

from collections import deque

import numpy as np

from daemon.planning.escape import field_at
from daemon.planning.grid import DIAGONAL, INF, OCCUPIED, STRAIGHT, Cell, path_cost
from daemon.planning.inflation import dilate
from daemon.planning.interface import GlobalPlanner

TRACK_CELLS = 400
"""Cells of track kept (40 m at 0.1 m cells): far more than a pocket's depth."""
TRACK_JUMP_CELLS = 4
"""A pose further than this from the last track cell is a relocalisation, not a walk: the
track starts again (the cells between were never shown passable)."""


class Track:
    """The cells the user stood on, oldest first, without loops, 8-connected."""

    def __init__(self, keep: int = TRACK_CELLS) -> None:
        self.cells: deque[Cell] = deque()
        self._keep = keep
        # The same cells as a set: the loop check at every step is a lookup, not a scan of up
        # to ``keep`` tuples (10.6 µs a step at 400 cells on the H100 machine's host).
        self._on: set[Cell] = set()

    def add(self, cell: Cell) -> None:
        if self.cells and self.cells[-1] == cell:
            return
        if self.cells:
            last = self.cells[-1]
            gap = max(abs(cell[0] - last[0]), abs(cell[1] - last[1]))
            if gap > TRACK_JUMP_CELLS:
                self.cells.clear()
                self._on.clear()
            elif gap > 1:  # a step of a few cells between poses: the line between was walked
                for k in range(1, gap):
                    t = k / gap
                    self._append((round(last[0] + t * (cell[0] - last[0])),
                                  round(last[1] + t * (cell[1] - last[1]))))  # fmt: skip
        self._append(cell)

    def _append(self, cell: Cell) -> None:
        if cell in self._on:  # back on a cell already walked: drop the loop
            while self.cells[-1] != cell:
                self._on.discard(self.cells.pop())
            return
        if len(self.cells) == self._keep:
            self._on.discard(self.cells.popleft())
        self.cells.append(cell)
        self._on.add(cell)


def track_out(
    planner: GlobalPlanner, blocked: np.ndarray, occupancy: np.ndarray, track: Track
) -> tuple[np.ndarray, int, np.ndarray]:
    """``(path, cost, lead)``: back along ``track`` (its newest cell is the user's) to the
    first cell with a planned path, then that path; ``lead`` is the part walked back.
    Empty and INF if the track crosses a known obstacle or no track cell has a path."""
    cells = np.array(track.cells, np.int32).reshape(-1, 2)
    none = np.empty((0, 2), np.int32)
    if len(cells) < 2:
        return none, int(INF), none
    back = cells[::-1]
    g = field_at(planner, back)
    for i in range(1, len(back)):
        r, c = int(back[i, 0]), int(back[i, 1])
        if occupancy[r, c] == OCCUPIED:
            break  # something stands on the track now: never lead into it
        if blocked[r, c] or g[i] >= INF:
            continue
        tail = planner.path((r, c))
        if len(tail) == 0:
            continue
        lead = back[:i]
        steps = np.abs(np.diff(back[: i + 1], axis=0)).sum(axis=1)
        lead_cost = int(np.where(steps == 2, DIAGONAL, STRAIGHT).sum())
        return np.vstack([lead, tail]).astype(np.int32), lead_cost + path_cost(tail), lead
    return none, int(INF), none


def dead_end_of(lead: np.ndarray, occupancy: np.ndarray, radius_cells: int) -> np.ndarray:
    """The cells to keep blocked once the user left a pocket along ``lead``: every lead cell
    (none had a path: the pocket, and the gap too narrow once inflated) and the obstacles
    within a gap's width of them (the gap's sides: forgotten out of view, they would widen
    the gap), inflated by the user's radius."""
    mark = np.zeros(occupancy.shape, bool)
    mark[lead[:, 0], lead[:, 1]] = True
    near = dilate(mark, 2 * radius_cells + 1) & (occupancy == OCCUPIED)
    return dilate(mark | near, radius_cells)
