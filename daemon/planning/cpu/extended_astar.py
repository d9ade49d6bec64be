"""Extended A* (Rettkowski, Gburek, Göhringer 2016, Table II): A* that keeps its open list small.

The same search as ``astar.py`` (the kernel ``astar_kernels.search``, parametrised, not
copied) with the paper's changes to classic A*:

- **Memory criterion** (their line 10): a neighbour is not opened when a blocked cell lies
  within ``clearance`` cells of it (Chebyshev distance: ``d`` steps of the 8-connected grid,
  which is what "nodes that are d nodes away" means on their grid). The window is clipped to
  the map (its edge is not a wall). The start is always opened; the goal is exempt (their
  line 9, the goal test, comes before the criterion).
  **Default ``clearance = 1``.** The paper gives no number: ``d`` is "defined by the robot's
  width", a safety distance. Guidebelt's ``blocked`` map is already inflated by the user's
  radius (``inflation.py``), so ``d`` is a margin on top of that; 1 is the smallest value that
  changes anything and keeps narrow passages (3 free cells wide) open.
- **An open neighbour is skipped** (their lines 12-13; the text: "a neighbor node that is
  already in L_o will be excluded"): the first way to reach a cell is kept, a cheaper later
  one is not looked at. (The "delete neighbor" of the listing is read as "do not insert it
  again": deleting the open cell would lose it, and the text says excluded.)
- **Goal on generation** (their line 9): the search stops when the goal is generated as a
  neighbour, not when it is popped.

What holds, exactly (``tests/daemon/planning/test_extended_astar.py`` property-tests it; the
rates are measured by ``sim/extended_astar_study.py``; BENCHMARKS.md has them):
- every path returned starts at the start, ends at the goal, steps between 8-neighbours
  through free cells only, and costs what ``cost_at`` says;
- its cost is >= the Dijkstra optimum (``dijkstra.dijkstra_field``), and not always equal:
  skipping open neighbours and stopping on generation both break optimality;
- when the goal is unreachable it answers no path (empty, INF), and the memory criterion can
  also make a reachable goal answer no path (a passage narrower than ``2 clearance + 1``
  cells, a start or goal boxed in by nearby obstacles); with ``clearance = 0`` a path is
  found exactly when one exists;
- every cell is opened at most once and closed at most once: a search ends after at most
  n expansions; bad input (goal outside, goal blocked, start outside or blocked, empty map)
  answers as ``astar`` and EDS do.

**Fallback** (``fallback=True``; not in the paper, on for the planner users get by name,
``registry.py``): when the memory criterion leaves no path, the same search runs again with
``d = 0``. A door the criterion closes is then still found (the courtyard's gaps are: the
paper's form answers no path on the 100² courtyard walk), a path is found exactly when one
exists, and the cost of a miss is one more search — counted in the statistics, and in
``fallbacks``. Off by default in the class, so the study measures the paper's form.

``costs()`` and ``costs_within()`` are inherited: they are the exact field (what the escape
from the margin reads to rank exits), not this planner's costs; ``escape.py`` skips an exit
from which this planner has no path.

Statistics as ``astar``: ``UpdateStats.iterations`` cells expanded, ``cells_touched`` cells
generated (opened), ``max_open`` the largest open-list size of the last search.
"""

from __future__ import annotations

import numpy as np

from ..grid import INF, Cell, in_bounds
from ..interface import UpdateStats
from .astar import HEURISTICS, TIE_BREAKS, AStarPlanner

DEFAULT_CLEARANCE = 1
"""The memory criterion's distance d in cells (the paper gives no number; see above)."""


class ExtendedAStarPlanner(AStarPlanner):
    """A* with the memory criterion, open neighbours skipped and the goal test on generation;
    each switch can be turned off to measure what it costs or saves."""

    def __init__(
        self,
        clearance: int = DEFAULT_CLEARANCE,
        skip_open: bool = True,
        goal_on_generation: bool = True,
        heuristic: str = "octile",
        tie_break: str = "exact",
        fallback: bool = False,
    ) -> None:
        if heuristic not in HEURISTICS:
            raise ValueError(f"unknown heuristic {heuristic!r}; choose one of {HEURISTICS}")
        if tie_break not in TIE_BREAKS:
            raise ValueError(f"unknown tie_break {tie_break!r}; choose one of {TIE_BREAKS}")
        if int(clearance) != clearance or clearance < 0:
            raise ValueError(f"clearance must be a whole number of cells >= 0, got {clearance!r}")
        super().__init__(heuristic, tie_break)
        self.clearance = int(clearance)
        self._clear_d = self.clearance
        self._skip_open = bool(skip_open)
        self._goal_on_generation = bool(goal_on_generation)
        self.fallback = bool(fallback)
        self.fallbacks = 0
        """Searches that found no path with the criterion and ran again with d = 0."""
        self._fell_back_for: object = None
        self.name = (
            f"extended-astar-cpu-d{self.clearance}"
            + ("" if tie_break == "exact" else f"-{tie_break}")
            + ("-fallback" if self.fallback else "")
        )

    def _search(self, start: Cell) -> tuple[np.ndarray, int]:
        path, cost = super()._search(start)
        key = ((int(start[0]), int(start[1])), self._version)
        if cost < INF or not self.fallback or self.clearance == 0 or self._fell_back_for == key:
            return path, cost
        if not in_bounds(self._shape, key[0]) or self._blk[self._padded(key[0])]:
            return path, cost  # no start: no search ran, none to repeat
        if self._blk[self._padded(self._goal)]:
            return path, cost
        first, first_open = self.search_stats, self.max_open
        self._cached = None  # the miss is cached under the same key
        self._clear_d = 0
        try:
            path, cost = super()._search(start)
        finally:
            self._clear_d = self.clearance
        self.fallbacks += 1
        self._fell_back_for = key
        second = self.search_stats
        if first is not None and second is not None:
            self.search_stats = UpdateStats(
                first.iterations + second.iterations,
                first.cells_touched + second.cells_touched,
                first.ms + second.ms,
            )
        self.max_open = max(first_open, self.max_open)
        return path, cost
