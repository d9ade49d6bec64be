"""The planner interface every backend implements (cpu ``fast``/``paper``, cuda, …).

Terms follow Díaz-Toro et al. 2022: ``g`` is the cost-to-goal field, ``pred`` the
predecessor (next cell towards the goal), ``incon`` the cells whose ``g`` may be wrong.

- **DSS** (``plan``/``replan``): the field from scratch.
- **EDS** (``update``): from the cells whose blocked state changed, set
  inconsistencies, propagate them, relax until nothing changes.

After every call ``costs()`` equals ``dijkstra.dijkstra_field`` cell for cell, and
``path(start)`` follows the fixed neighbour order of ``grid.py``, so every backend
walks the same cells.
"""

from __future__ import annotations

import time
from abc import ABC, abstractmethod
from dataclasses import dataclass

import numpy as np

from .grid import INF, NEIGHBOUR_COST, NEIGHBOUR_DC, NEIGHBOUR_DR, Cell, in_bounds


@dataclass(frozen=True, slots=True)
class UpdateStats:
    """What one planning call cost. (Slots: made at every step, and a frozen dataclass
    without them takes ~0.9 µs to build, with them ~0.55.)"""

    iterations: int
    """Relaxation rounds (whole-grid sweeps for ``paper``, queue pops for ``fast``…)."""
    cells_touched: int
    """Cells whose g was read and relaxed (or written), a backend-independent effort measure."""
    ms: float
    """Wall time of the call, including any device synchronisation."""


class Planner(ABC):
    """Keeps the cost-to-goal field ``g`` of one map and one goal up to date."""

    name: str = "planner"

    @abstractmethod
    def plan(self, blocked: np.ndarray, goal: Cell) -> UpdateStats:
        """DSS: copy ``blocked`` (``bool``, (h, w)) and ``goal``; compute g from scratch."""

    @abstractmethod
    def update(self, cells: np.ndarray, blocked: np.ndarray) -> UpdateStats:
        """EDS: set ``blocked[cells] = blocked`` (flat int64 indices); repair g incrementally."""

    @abstractmethod
    def replan(self, cells: np.ndarray, blocked: np.ndarray) -> UpdateStats:
        """DSS after a change: apply the same change as ``update``, then recompute from scratch."""

    @abstractmethod
    def costs(self) -> np.ndarray:
        """A host copy of g (``int32``, (h, w))."""

    @abstractmethod
    def blocked(self) -> np.ndarray:
        """A host copy of the planner's blocked map."""

    @abstractmethod
    def cost_at(self, cell: Cell) -> int:
        """g at one cell (INF if unreachable, blocked or out of the map)."""

    @abstractmethod
    def path(self, start: Cell) -> np.ndarray:
        """Cells from ``start`` to the goal, ``(k, 2) int32``; empty (0, 2) if none."""

    def update_and_path(
        self, cells: np.ndarray, blocked: np.ndarray, start: Cell, *, full: bool = False
    ) -> tuple[UpdateStats, np.ndarray]:
        """One replanning step: ``replan`` (``full``, DSS) or ``update`` (EDS), then ``path``.

        The returned statistics' ``ms`` covers both calls. Device backends override this to
        queue the repair, the path and the read-back of both with one synchronisation.
        """
        t0 = time.perf_counter()
        stats = self.replan(cells, blocked) if full else self.update(cells, blocked)
        path = self.path(start)
        ms = (time.perf_counter() - t0) * 1e3
        return UpdateStats(stats.iterations, stats.cells_touched, ms), path

    @property
    @abstractmethod
    def goal(self) -> Cell: ...

    @property
    @abstractmethod
    def shape(self) -> tuple[int, int]: ...


def reference_path(g: np.ndarray, blocked: np.ndarray, start: Cell) -> np.ndarray:
    """Follow predecessors through ``g`` with the fixed neighbour order (pure Python).

    The first neighbour ``n`` in ``grid.NEIGHBOUR_*`` order with ``g[n] + cost == g[cur]``
    is the predecessor. Backends implement the same rule compiled; tests compare with this.
    """
    h, w = g.shape
    if not in_bounds((h, w), start) or blocked[start] or g[start] >= INF:
        return np.empty((0, 2), dtype=np.int32)
    out = [start]
    r, c = start
    while g[r, c] != 0:
        for dr, dc, cost in zip(NEIGHBOUR_DR, NEIGHBOUR_DC, NEIGHBOUR_COST, strict=True):
            nr, nc = r + int(dr), c + int(dc)
            if (
                0 <= nr < h
                and 0 <= nc < w
                and not blocked[nr, nc]
                and int(g[nr, nc]) + int(cost) == int(g[r, c])
            ):
                r, c = nr, nc
                break
        else:
            raise RuntimeError(f"g is not a consistent cost field at {(r, c)}")
        out.append((r, c))
    return np.array(out, dtype=np.int32)


def reference_pred(g: np.ndarray, blocked: np.ndarray) -> np.ndarray:
    """``pred`` map (``int8`` neighbour index, -1 for goal/blocked/unreachable) from g."""
    h, w = g.shape
    pred = np.full((h, w), -1, dtype=np.int8)
    gp = np.pad(g.astype(np.int64), 1, constant_values=int(INF))
    bp = np.pad(blocked, 1, constant_values=True)
    undecided = (~blocked) & (g < INF) & (g > 0)
    for k in range(8):
        dr, dc = int(NEIGHBOUR_DR[k]), int(NEIGHBOUR_DC[k])
        gn = gp[1 + dr : 1 + dr + h, 1 + dc : 1 + dc + w]
        bn = bp[1 + dr : 1 + dr + h, 1 + dc : 1 + dc + w]
        hit = undecided & ~bn & (gn + int(NEIGHBOUR_COST[k]) == g)
        pred[hit] = k
        undecided &= ~hit
    return pred


def checked_plan_input(blocked: np.ndarray, goal: Cell) -> tuple[np.ndarray, tuple[int, int], Cell]:
    """``(blocked as bool, shape, goal as ints)`` for ``plan``; ValueError on a bad map or goal."""
    blocked = np.asarray(blocked, dtype=bool)
    if blocked.ndim != 2 or blocked.size == 0:
        raise ValueError(f"blocked must be a non-empty 2-D map, got shape {blocked.shape}")
    shape = (int(blocked.shape[0]), int(blocked.shape[1]))
    goal = (int(goal[0]), int(goal[1]))
    if not in_bounds(shape, goal):
        raise ValueError(f"goal {goal} is outside the {shape[0]}x{shape[1]} map")
    return blocked, shape, goal
GlobalPlanner = Planner
