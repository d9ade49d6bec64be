"""GA+A* behind the planner interface (Ghoniem et al., Algorithms 1-2 and Section 4.4).

``path(start)`` answers with the path of ``genetic.evolve`` from ``start`` to the goal on the
current map: the GA of Algorithm 1 with A* between consecutive waypoints as the fitness
(Algorithm 2), seeded from ``GaParams.seed`` and the two ends, so the same map, start, goal
and parameters give the same path.

**Rerouting (Section 4.4).** The paper plans once and computes "a new route ... from the
person's current position" only "if any obstacle is found in the path". So does this
planner (``keep_route=True``, the default): after a GA run it keeps the path, and a later
``path(cell)`` from a cell on it whose remaining cells are all still free answers with the
rest of that path, without a GA run. A cell off the path, a newly blocked cell on the rest
of it, or a new goal (``plan``) runs the GA again from the user's cell. That run carries the
old route over: one chromosome of its initial population is the old route's cells spread
evenly from the one nearest the user to the goal, so the answer is never dearer (by Eq. 2)
than rejoining the old route, and a user who drifts a cell off it is not sent round the other
side of an obstacle by a fresh random draw (without it, 3 of 120 belt walks of ``guidebelt
walks`` dithered between two routes until the action limit). So a walk with this planner
depends on its history as the paper's does; a fresh planner (or ``keep_route=False``)
answers every ``path(start)`` with the GA's answer for that map and start alone.

What it keeps from ``AStarPlanner`` (it is one, with the search swapped): the map
(``plan``/``update``/``blocked``), bad input (a goal outside the map is a ValueError from
``plan``; a goal or start that is blocked, a start outside the map or cut off from the goal
answer the empty path and INF), and the exact field for the escape from the margin
(``costs``, ``costs_within``: the exact cost-to-goal, not this planner's costs, as for
extended A*).

``cost_at(cell)`` is the cost of what ``path(cell)`` would answer now (without changing the
kept path): the GA's cost, not the optimum. Not optimal: a GA path is never cheaper than
A*'s and often dearer; ``sim/ga_study.py`` measures by how much.

Statistics: ``UpdateStats.iterations`` is the A* segment searches of the GA run (0 when the
kept path answered), ``cells_touched`` the cells they expanded; ``max_open`` the largest open
list of any of them; ``search_stats`` as for A* (the navigator records it per path read);
``ga_runs`` counts GA runs.
"""

from __future__ import annotations

import time

import numpy as np

from ..grid import INF, Cell, in_bounds, path_cost
from ..interface import UpdateStats
from .astar import AStarPlanner
from .genetic import GaParams, GaResult, Segments, evolve

_EMPTY = np.empty((0, 2), dtype=np.int32)


class GaAStarPlanner(AStarPlanner):
    """Ghoniem et al.'s GA with A* fitness; CPU only."""

    def __init__(self, params: GaParams | None = None, keep_route: bool = True) -> None:
        super().__init__()
        self.params = params or GaParams()
        self.keep_route = keep_route
        self.name = f"ga-astar-cpu-p{self.params.population}g{self.params.generations}" + (
            f"w{self.params.waypoints}"
        )
        self._segments = Segments()
        self._route: np.ndarray = _EMPTY
        self._route_goal: Cell | None = None
        self._answers: dict[tuple[Cell, int, int], tuple[np.ndarray, int]] = {}
        self._route_id = 0
        self.ga_runs = 0
        self.last: GaResult | None = None
        """The last GA run's result (None before one)."""

    def plan(self, blocked: np.ndarray, goal: Cell) -> UpdateStats:
        stats = super().plan(blocked, goal)
        self._route, self._route_goal = _EMPTY, None
        return stats

    # -- answers ----------------------------------------------------------------------------

    def _kept(self, start: Cell) -> np.ndarray | None:
        """The rest of the kept path from ``start`` when it is on it and still free."""
        route = self._route
        if not self.keep_route or len(route) == 0 or self._route_goal != self._goal:
            return None
        at = np.flatnonzero((route[:, 0] == start[0]) & (route[:, 1] == start[1]))
        if at.size == 0:
            return None
        rest = route[int(at[0]) :]
        if self.blocked_cells(rest).any():
            return None
        return rest

    def blocked_cells(self, cells: np.ndarray) -> np.ndarray:
        """Whether each cell of ``cells`` ((k, 2), inside the map) is blocked now."""
        return self._blk[(cells[:, 0] + 1) * self._width + cells[:, 1] + 1].astype(bool)

    def _carried(self, start: Cell) -> list[Cell] | None:
        """The kept route's cells spread evenly from the one nearest ``start`` to the goal."""
        route = self._route
        if not self.keep_route or len(route) < 2 or self._route_goal != self._goal:
            return None
        near = int(np.argmax(-np.abs(route - np.asarray(start)).max(axis=1)))
        ahead = route[near:-1]
        if len(ahead) == 0:
            return None
        m = self.params.waypoints
        at = np.linspace(0, len(ahead) - 1, m + 2)[1:-1].round().astype(int)
        return [(int(ahead[i, 0]), int(ahead[i, 1])) for i in at]

    def _evolve(self, start: Cell) -> tuple[np.ndarray, int]:
        """The GA's answer from ``start`` on the current map (remembered per map version and
        kept route)."""
        key = (start, self._version, self._route_id if self.keep_route else 0)
        hit = self._answers.get(key)
        if hit is not None:
            self.search_stats = UpdateStats(0, 0, 0.0)
            return hit
        if len(self._answers) > 64:  # answers of older maps are never asked for again
            self._answers.clear()
        carried = self._carried(start)
        result = evolve(self.blocked(), start, self._goal, self.params, self._segments, carried)
        self.ga_runs += 1
        self.last = result
        self.max_open = result.max_open
        self.search_stats = UpdateStats(result.searches, result.expanded, result.ms)
        hit = (result.path, result.cost)
        self._answers[key] = hit
        return hit

    def _answer(self, start: Cell) -> tuple[np.ndarray, int, bool]:
        """(path, cost, from the kept path?) from ``start``."""
        start = (int(start[0]), int(start[1]))
        if self._shape == (0, 0) or not in_bounds(self._shape, start):
            return _EMPTY, int(INF), False
        t0 = time.perf_counter()
        rest = self._kept(start)
        if rest is not None:
            self.search_stats = UpdateStats(0, 0, (time.perf_counter() - t0) * 1e3)
            return rest, path_cost(rest), True
        path, cost = self._evolve(start)
        return path, cost, False

    def path(self, start: Cell) -> np.ndarray:
        path, _, kept = self._answer(start)
        if not kept and len(path):
            self._route, self._route_goal = path, self._goal
            self._route_id += 1
        return path.copy()

    def cost_at(self, cell: Cell) -> int:
        return self._answer(cell)[1]
