"""The paper's closed loop: sense → inflate → replan → step one cell → repeat until the goal.

The daemon's ``Navigator`` does the work (``closed_loop.run_walk``): each step the sensor's
delta and the user's pose go in; the navigator inflates the delta by the user's radius
(``inflate_ms``), repairs its field — EDS (planner ``eds``) or DSS (``dss``) — and reads the
path from the user's cell in one planner call (``step_ms``: the paper's "replanning step",
wall clock, with any device synchronisation), then turns the path into a belt pattern
(``guide_ms``); ``nav_ms`` is the whole step. The user, a ``PathWalker``, moves to the next
cell of the path and faces half a metre ahead along it; arrival is the goal cell itself, as
in the paper.

Both modes compute the same exact field and read the path with the same neighbour order,
so EDS and DSS walk the same cells; only their cost differs. ``astar`` searches from the
user's cell at every step: paths of the same cost, not always the same cells.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from daemon.navigation import Navigator, NavigatorSettings
from daemon.planning.grid import Cell
from daemon.planning.registry import PLANNERS

from .closed_loop import Walk, run_walk
from .courtyard import Scenario
from .world import World

MODES = PLANNERS
"""The planners a walk can run: every one the registry knows."""

StepCallback = Callable[[int, Cell, int, float], None]
"""``on_step(step, cell, cells_changed, step_ms)`` after each step."""


@dataclass(frozen=True)
class WalkPicture:
    """What a picture shows of a walk (``render.py``); the zenoh walk makes one too."""

    mode: str
    arrived: bool
    reason: str
    """``arrived``, ``no path`` (the goal cannot be reached from the user) or ``step limit``."""
    walked: np.ndarray
    """``(steps + 1, 2) int32``: the cells the user stood on, start first."""
    known: np.ndarray
    """The known occupancy at the end of the walk."""
    blocked: np.ndarray
    """The inflated known map at the end of the walk."""
    cell_m: float

    @property
    def steps(self) -> int:
        return len(self.walked) - 1

    @property
    def walked_m(self) -> float:
        if len(self.walked) < 2:
            return 0.0
        d = np.abs(np.diff(self.walked.astype(np.int64), axis=0)).sum(axis=1)
        return float(np.where(d == 2, math.sqrt(2.0), 1.0).sum() * self.cell_m)


@dataclass(frozen=True)
class WalkResult(WalkPicture):
    """What one walk did, step by step (arrays have one entry per replanning step)."""

    planner: str
    iterations: np.ndarray
    cells_touched: np.ndarray
    plan_ms: np.ndarray
    """The planner's own time for the repair + path (its ``UpdateStats.ms``)."""
    step_ms: np.ndarray
    """Wall clock around the repair, the path read and its cost: the replanning step."""
    inflate_ms: np.ndarray
    guide_ms: np.ndarray
    nav_ms: np.ndarray
    """The navigator's whole step: map, planner, guidance, status."""
    idle_ms: np.ndarray
    """After the step, its outputs out: the planner's work left for then (not in the step)."""
    changed: np.ndarray
    """Cells whose blocked state flipped at this step."""
    init_ms: float
    """The first full plan on the known map (the walk's first step), before the walk."""
    max_open: np.ndarray
    """The largest open list of each step's search (A*); -1 where the planner keeps a field."""


def paper_settings(scenario: Scenario, mode: str, backend: str, variant: str) -> NavigatorSettings:
    """The navigator as the paper's walk runs it: its radius, arrival on the goal cell."""
    return NavigatorSettings(
        planner=mode,
        backend=backend,
        variant=variant,
        cell_m=scenario.cell_m,
        user_radius_m=scenario.radius_cells * scenario.cell_m,
        arrive_m=scenario.cell_m / 2,  # on the goal cell, not beside it
    )


def walk(
    scenario: Scenario,
    backend: str = "cpu",
    variant: str = "fast",
    mode: str = "eds",
    fov_deg: float = 80.0,
    max_steps: int | None = None,
    navigator: Navigator | None = None,
    on_step: StepCallback | None = None,
) -> WalkResult:
    """Walk ``scenario`` from start to goal, replanning every step; ``navigator`` overrides."""
    if mode not in MODES:
        raise ValueError(f"unknown mode {mode!r}; choose one of {MODES}")
    nav = navigator or Navigator("walk", paper_settings(scenario, mode, backend, variant))
    h, w = scenario.shape
    max_steps = max_steps if max_steps is not None else 10 * (h + w)
    world = World(scenario, "path", fov_deg=fov_deg)

    def report(progress: Walk) -> None:
        if on_step is not None and progress.reports:
            last = progress.reports[-1]
            on_step(progress.steps, progress.walked[-1], last.changed, last.plan.plan_ms)

    # One more navigator step than walked steps: the last one says ARRIVED. A path walker
    # steps at every action unless it bumps, so the action limit is only a backstop.
    done = run_walk(world, nav, max_actions=4 * max_steps + 1, max_steps=max_steps, step_s=1.0,
                    on_step=report)  # fmt: skip
    # The steps before the first plan set the walk up; the first plan is its init_ms.
    first = next((i for i, r in enumerate(done.reports) if r.plan.planned), len(done.reports))
    reports = done.reports[first + 1 :]
    stats = [r.plan.stats for r in reports]

    def column(values: list, dtype: type) -> np.ndarray:
        return np.array(values, dtype=dtype)

    grid = nav.maps.map
    assert grid is not None
    return WalkResult(
        mode=mode,
        planner=nav.route.name,
        arrived=done.arrived,
        reason=done.reason,
        walked=np.array(done.walked, dtype=np.int32),
        iterations=column([s.iterations if s else 0 for s in stats], np.int64),
        cells_touched=column([s.cells_touched if s else 0 for s in stats], np.int64),
        plan_ms=column([s.ms if s else 0.0 for s in stats], np.float64),
        step_ms=column([r.plan.plan_ms for r in reports], np.float64),
        inflate_ms=column([r.inflate_ms for r in reports], np.float64),
        guide_ms=column([r.guide_ms for r in reports], np.float64),
        nav_ms=column([r.step_ms for r in reports], np.float64),
        idle_ms=column([r.idle_ms for r in reports], np.float64),
        changed=column([r.changed for r in reports], np.int64),
        max_open=column(
            [-1 if r.plan.max_open is None else r.plan.max_open for r in reports], np.int64
        ),
        init_ms=done.reports[first].plan.plan_ms if first < len(done.reports) else math.nan,
        known=grid.occupancy.copy(),
        blocked=grid.blocked.copy(),
        cell_m=scenario.cell_m,
    )
