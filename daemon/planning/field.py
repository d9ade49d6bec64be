"""What the EDS and DSS planners share beyond the interface: one field, two ways to update it.

Díaz-Toro et al. 2022 compare two planners on the same field ``g``: **DSS** computes it from
scratch after every change, **EDS** repairs it from the changed cells (set inconsistencies,
propagate them, relax until nothing changes). Each backend implements both, as ``_recompute``
and ``_repair``; the registry builds it as one or the other (``dss``), so the navigator sees a
planner whose ``update`` is just "bring the field up to date". Either way, after every call
``costs()`` equals ``dijkstra.dijkstra_field`` cell for cell.
"""

from __future__ import annotations

from abc import abstractmethod

import numpy as np

from .grid import Cell, checked_plan_input
from .interface import GlobalPlanner, UpdateStats


class FieldPlanner(GlobalPlanner):
    """An EDS (``dss=False``) or DSS planner on one backend; ``name`` is e.g. ``eds-cpu-fast``."""

    backend = "cpu"
    variant = "fast"
    _goal: Cell = (0, 0)
    _shape: tuple[int, int] = (0, 0)

    def __init__(self, dss: bool = False) -> None:
        self.dss = dss
        self.name = f"{'dss' if dss else 'eds'}-{self.backend}-{self.variant}"

    @property
    def goal(self) -> Cell:
        return self._goal

    @property
    def shape(self) -> tuple[int, int]:
        return self._shape

    def _take_plan(self, blocked: np.ndarray, goal: Cell) -> np.ndarray:
        """``plan``'s input checked (ValueError), the maps sized for it, the goal kept; returns
        the map as ``bool``."""
        blocked, shape, goal = checked_plan_input(blocked, goal)
        if shape != self._shape:
            self._allocate(shape)
        self._goal = goal
        return blocked

    def _allocate(self, shape: tuple[int, int]) -> None:
        """Size the planner's maps for ``shape`` (and remember it)."""
        self._shape = shape

    def update(self, cells: np.ndarray, blocked: np.ndarray) -> UpdateStats:
        return self._recompute(cells, blocked) if self.dss else self._repair(cells, blocked)

    @abstractmethod
    def _repair(self, cells: np.ndarray, blocked: np.ndarray) -> UpdateStats:
        """EDS: apply the change, repair g from the changed cells."""

    @abstractmethod
    def _recompute(self, cells: np.ndarray, blocked: np.ndarray) -> UpdateStats:
        """DSS: apply the change, compute g from scratch."""

    @abstractmethod
    def costs(self) -> np.ndarray:
        """A host copy of g (``int32``, (h, w))."""

    @abstractmethod
    def blocked(self) -> np.ndarray:
        """A host copy of the planner's blocked map (``bool``, (h, w))."""
