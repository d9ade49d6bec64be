"""The global planner interface: what the navigator calls, and nothing more.

Five calls, as Nav2's ``GlobalPlanner`` has: ``plan`` a map and goal, ``update`` after a
change, ``path`` and ``cost_at`` from a cell, and ``update_and_path`` (one replanning step,
which a device backend serves in one round trip); and ``between_steps``, where a planner may
do what its steps left for later, once the user has their answer. The planners of the other
papers register behind the same interface (``registry.register``), so it stays this small;
what only the EDS/DSS backends offer (a host copy of ``g``, the blocked map, per-call
statistics of their own) lives on those classes.

Terms follow Díaz-Toro et al. 2022: ``g`` is the cost-to-goal field. For the EDS and DSS
planners, after every call ``g`` equals ``dijkstra.dijkstra_field`` cell for cell, and
``path(start)`` follows the fixed neighbour order of ``grid.py``, so every backend walks the
same cells. The ``astar`` planner keeps no field: its paths have the same cost, not always
the same cells (``cpu/astar.py``).
"""

from __future__ import annotations

import time
from abc import ABC, abstractmethod
from dataclasses import dataclass

import numpy as np

from .grid import Cell


@dataclass(frozen=True, slots=True)
class UpdateStats:
    """What one planning call cost. (Slots: one is made at every step, and a frozen dataclass
    without them takes nearly twice as long to build.)"""

    iterations: int
    """Relaxation rounds (whole-grid sweeps for ``paper``, queue pops for ``fast``, cells
    expanded for ``astar``…)."""
    cells_touched: int
    """Cells whose g was read and relaxed (or written), a backend-independent effort measure
    (for ``astar``: cells generated)."""
    ms: float
    """Wall time of the call, including any device synchronisation."""


class GlobalPlanner(ABC):
    """Keeps a cost-to-goal field of one map and one goal up to date."""

    name: str = "planner"

    @abstractmethod
    def plan(self, blocked: np.ndarray, goal: Cell) -> UpdateStats:
        """Copy ``blocked`` (``bool``, (h, w)) and ``goal``; compute the field from scratch."""

    @abstractmethod
    def update(self, cells: np.ndarray, blocked: np.ndarray) -> UpdateStats:
        """Set ``blocked[cells] = blocked`` (flat int64 indices) and bring the field up to date:
        EDS repairs it, DSS recomputes it. A cell outside the map is an IndexError and nothing
        is applied."""

    @abstractmethod
    def path(self, start: Cell) -> np.ndarray:
        """Cells from ``start`` to the goal, ``(k, 2) int32``; empty (0, 2) if none."""

    @abstractmethod
    def cost_at(self, cell: Cell) -> int:
        """The field at one cell (INF if unreachable, blocked or out of the map)."""

    def update_and_path(
        self, cells: np.ndarray, blocked: np.ndarray, start: Cell
    ) -> tuple[UpdateStats, np.ndarray]:
        """One replanning step: ``update``, then ``path``; the statistics' ``ms`` covers both.
        Device backends override it to do both with one synchronisation."""
        t0 = time.perf_counter()
        stats = self.update(cells, blocked)
        path = self.path(start)
        ms = (time.perf_counter() - t0) * 1e3
        return UpdateStats(stats.iterations, stats.cells_touched, ms), path

    def between_steps(self) -> None:  # noqa: B027 (a hook: most planners leave nothing)
        """Work that may wait until the step's answer is out (the user's outputs published):
        none, for most planners."""

    @property
    @abstractmethod
    def goal(self) -> Cell: ...

    @property
    @abstractmethod
    def shape(self) -> tuple[int, int]: ...
