"""The cuda backend's EDS on a small grid: the host's CPU repair serves the steps.

A cuda step is a round trip — the host posts the change into the resident loop's mailbox,
the device's blocks pick it up, settle, extract the path and write it back, the host sees
the done word — of 0.06–0.08 ms at its median on an H200 host at 100² and 200², whatever the
change. The CPU repair (``cpu/repair.py``: a walking step's change, repair and path in one
compiled call) does the whole step in 0.03–0.05 ms there. The GPU's DSS, against which EDS is
measured, stays on the device. The cuda backend's EDS plans a map of at most ``SMALL_CELLS``
cells with ``FastCpuPlanner`` and a larger one with ``CudaPlanner``; the choice is made at each
``plan`` (a new map), never in the middle of a walk. Both compute the same exact field and read
the same path, tie for tie, so the rule changes what a step costs, never where the user is led.
Only EDS (``fast``) is switched.

The limit, measured on H100 hosts (2026-11-27; four scenarios at 20/40/60 %): at 200², the
limit at 200² and at 100² interleaved three times on one host, the CPU repair's p99 came above
the device DSS's in 8 of 36 walks (up to 2.05 ×), the device's EDS (``deferred_blocks.py`` in
front of it) failed in 2 of 36 (a p99 0.170 against 0.161 ms, a walk 0.51 of DSS's); at 100²,
on another host, the device's EDS walked more than half DSS's time in 12 of 24 walks (up to
0.67). So the limit is 100² (200² before the device's EDS answered steps on the host).

``name`` is the planner that serves the current map (``eds-cpu-fast`` on a small one), so a
bench row or a log line says which one ran. ``parts`` lists both, for the warm-up: the kernels
are compiled before the first large map even though the warm-up's map is small.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from ..cpu.fast import FastCpuPlanner
from ..grid import Cell
from ..interface import GlobalPlanner, UpdateStats

if TYPE_CHECKING:
    from .combine import Combiner
    from .planner import CudaPlanner
    from .posting import Post

SMALL_CELLS = 100 * 100
"""Grids of at most this many cells are planned on the CPU (the module's measurements)."""


class SmallGridsOnCpu(GlobalPlanner):
    """Cuda EDS whose maps of at most ``small_cells`` cells are planned by the CPU repair."""

    backend = "cuda"
    # Neither planner it serves searches at a path read, so neither has these; the route reads
    # both at every step (``getattr(planner, ..., None)``). Answered here rather than by
    # ``__getattr__``, whose AttributeError, raised from Python at every step, cost EDS 2.5 µs
    # hot and ~10 µs cold a step on the dev VM where DSS (a ``CudaPlanner`` itself) paid none.
    max_open = None
    search_stats = None

    def __init__(self, variant: str = "fast", small_cells: int = SMALL_CELLS) -> None:
        self.variant = variant
        self.dss = False
        self.small_cells = small_cells
        self._cpu: FastCpuPlanner | None = None
        self._cuda: CudaPlanner | None = None
        self._serving: GlobalPlanner | None = None
        self._steps: Combiner[Post] | None = None  # the device's step combiner, once cuda() ran

    @property
    def name(self) -> str:  # type: ignore[override]
        return self._serving.name if self._serving else f"eds-cuda-{self.variant}"

    def cpu(self) -> FastCpuPlanner:
        if self._cpu is None:
            self._cpu = FastCpuPlanner()
        return self._cpu

    def cuda(self) -> CudaPlanner:
        if self._cuda is None:  # imported here: a host without cupy plans small maps all the same
            from .planner import CudaPlanner
            from .posting import STEPS

            self._cuda = CudaPlanner(self.variant)
            self._steps = STEPS  # read by shared_now between every step: no import there
        return self._cuda

    def parts(self) -> list[GlobalPlanner]:
        """Both planners, for a warm-up that must run each one's code once."""
        return [self.cpu(), self.cuda()]

    def _planned(self) -> GlobalPlanner:
        if self._serving is None:
            raise RuntimeError("call plan(blocked, goal) before update")
        return self._serving

    def plan(self, blocked: np.ndarray, goal: Cell) -> UpdateStats:
        small = np.size(blocked) <= self.small_cells
        self._serving = serving = self.cpu() if small else self.cuda()
        # Every walking step is one update_and_path: the serving planner's own, bound here, so
        # a step pays no forwarding frames (``update_and_path`` below serves before a plan).
        self.update_and_path = serving.update_and_path  # type: ignore[method-assign]
        return serving.plan(blocked, goal)

    def update(self, cells: np.ndarray, blocked: np.ndarray) -> UpdateStats:
        return self._planned().update(cells, blocked)

    def update_and_path(
        self, cells: np.ndarray, blocked: np.ndarray, start: Cell
    ) -> tuple[UpdateStats, np.ndarray]:
        return self._planned().update_and_path(cells, blocked, start)

    def path(self, start: Cell) -> np.ndarray:
        return self._planned().path(start)

    def cost_at(self, cell: Cell) -> int:
        return self._planned().cost_at(cell)

    @property
    def goal(self) -> Cell:
        return self._planned().goal

    @property
    def shape(self) -> tuple[int, int]:
        return self._serving.shape if self._serving else (0, 0)

    def shared_now(self) -> bool:
        """Whether other threads' steps have met this process's on the device lately
        (``combine.py``): work that can wait had better ride with a later step than make a
        post of its own (``DeferredBlocks.between_steps``)."""
        steps = self._steps  # set with the cuda planner: serving it means it is there
        return steps is not None and self._serving is self._cuda and steps.contended

    def __getattr__(self, attr: str):
        # What only some planners offer (costs, costs_within, settle, pending, blocked, the
        # cuda planner's statistics) comes from the one serving the map: a caller that asks
        # with getattr(planner, attr, None) sees exactly what that planner has.
        if attr.startswith("_") or self.__dict__.get("_serving") is None:
            raise AttributeError(attr)
        return getattr(self.__dict__["_serving"], attr)
