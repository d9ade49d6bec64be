"""The planner of one user's map and goal: plans, repairs, reads paths, survives the device.

``Route`` owns the planner the registry built for the navigator's settings. The changes of a
step wait (``change``) until the step reads its path, so the repair and the path go to the
planner in one ``update_and_path`` call (one round trip on the GPU).

A CUDA failure moves this user to the CPU: the navigator owns the map, so the new CPU planner
is planned from that map, which already holds every change, and the failed call is simply
asked again. Nothing needs a mirror of the device's state.
"""

from __future__ import annotations

import logging
import time
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from daemon.planning import device_errors
from daemon.planning.escape import escape_path
from daemon.planning.grid import INF, Cell, path_cost
from daemon.planning.inflation import InflatedMap
from daemon.planning.interface import GlobalPlanner, UpdateStats

from .pocket import Track, dead_end_of, track_out

log = logging.getLogger("guidebelt.navigation")

NARROWER_CELLS = 1
"""How many cells less than the user's radius the last resort may keep: one, the cell a
camera's obstacle bleeds beside its face. (Down to one cell, seed 1 of the camera walks
arrived with 7 collisions; which of its paths bumped was not traced.)"""

PlannerFactory = Callable[[str], GlobalPlanner]
"""``factory(backend) -> planner``; the navigator asks for ``"cpu"`` after a device failure."""


@dataclass(slots=True)
class PlanReport:
    """What the planner did in one step (for status, the simulator and the benchmark)."""

    stats: UpdateStats | None = None
    """The repair's statistics; None when the step changed nothing the planner had."""
    plan_ms: float = 0.0
    """Wall time of every planner call in the step: plan, repair and path read."""
    planned: bool = False
    """The step planned from scratch (a new map or goal, or a move to the CPU)."""
    max_open: int | None = None
    """The largest open list of the step's search, from a planner that searches (A*)."""
    back_along_track: bool = False
    """No plan and no escape from where the user stands (a pocket): the path leads back
    along the user's own track (``pocket``)."""
    narrower_cells: int | None = None
    """Neither: the path keeps this smaller clearance (cells) instead of the user's radius."""

    def way_out(self, cell_m: float) -> str:
        """What the status says of a path that is not the plain one (the belt guides along
        it as along any path)."""
        if self.back_along_track:
            return "dead end: back along your track"
        if self.narrower_cells is not None:
            return f"narrow way: clearance {self.narrower_cells * cell_m:.1f} m"
        return ""


class Route:
    def __init__(
        self, factory: PlannerFactory, backend: str, escape_reach: int, radius_cells: int = 3
    ) -> None:
        self._factory = factory
        self._radius = radius_cells
        self.track = Track()
        self.dead: np.ndarray | None = None
        """Cells kept blocked for the planner: dead ends the user was led out of (this goal)."""
        self._may_narrow = True
        self._leaving: np.ndarray | None = None
        """The dead end of the way out of a pocket, kept once the user stands clear of it."""
        self.planner = factory(backend)
        self._escape_reach = escape_reach
        self._errors = device_errors()
        self._planned = False
        self._pending: tuple[np.ndarray, np.ndarray] | None = None
        self.fallback_reason: str | None = None
        self.report = PlanReport()
        self._kept: tuple[GlobalPlanner, Cell, Cell, np.ndarray, int] | None = None
        """(planner, cell, goal, path, cost) of the last plain path read: a field planner whose
        field nothing changed since reads the same path from the same cell again."""

    @property
    def name(self) -> str:
        return self.planner.name

    def invalidate(self) -> None:
        """A new map or goal: the next path plans from scratch (which includes any change)."""
        self._planned = False
        self._pending = None
        self._kept = None

    def forget_dead_ends(self) -> None:
        """A new goal: a pocket is a dead end only on the way to the goal it was met for."""
        self._leaving = None
        if self.dead is not None:
            self.dead = None
            self.invalidate()

    def change(self, flipped: np.ndarray, blocked_now: np.ndarray) -> None:
        """Cells whose blocked state flipped; given to the planner with the next path read."""
        self._kept = None
        if not self._planned:
            return  # the next plan reads the whole map
        if self.dead is not None:  # a dead end stays blocked whatever the map says of it
            blocked_now = blocked_now | self.dead.reshape(-1)[flipped]
        if self._pending is not None:  # a second batch in one step (rare): hand over the first
            self.settle()
        self._pending = (flipped, blocked_now)

    def settle(self) -> None:
        """Give the planner the step's changes when the step reads no path."""
        if self._pending is not None:
            self._kept = None
            self._guarded(lambda p: self._record(p.update(*self._take())), retry=False)

    def between_steps(self) -> None:
        """The planner's work left for after the step's outputs (a device error: the CPU).
        Any other failure leaves what the planner holds unknown: the next path plans afresh."""
        if not self._planned:
            return
        try:
            self._guarded(lambda p: p.between_steps(), retry=False)
        except Exception:
            self.invalidate()
            raise

    def path_from(
        self,
        blocked: np.ndarray,
        occupancy: np.ndarray,
        goal: Cell,
        cell: Cell,
        narrower: bool = True,
    ) -> tuple[np.ndarray, int]:
        """The path from ``cell`` to ``goal`` and its cost (empty and INF if none).

        From inside the inflation margin (a newly seen obstacle grew over the user, or the user
        drifted into it), or from a free pocket the margin encloses, the path first leads
        straight out to the nearest usable free cell; failing that, back along the user's
        track (``pocket``); failing that, and where ``narrower`` allows (the map is inflated
        by the user's radius alone), with less clearance.
        """
        t0 = time.perf_counter()
        self.report = PlanReport()
        self._may_narrow = narrower
        self.track.add(cell)
        if self.dead is not None and self.dead.shape != blocked.shape:
            self.dead, self._leaving = None, None  # a map of another shape: start over
        # The step's call without ``_guarded``'s closure and two frames (every step runs this):
        # the same fallback, the call asked again on the CPU.
        try:
            result = self._path(self.planner, blocked, occupancy, goal, cell)
        except self._errors as exc:
            self._fall_back(exc)
            result = self._path(self.planner, blocked, occupancy, goal, cell)
        if len(result[0]) == 0 and self.dead is not None:
            # The remembered dead ends leave no way at all: the map decides, not the memory.
            self.dead, self._leaving = None, None
            self.invalidate()
            result = self._guarded(lambda p: self._path(p, blocked, occupancy, goal, cell), True)
        self.report.plan_ms = (time.perf_counter() - t0) * 1e3
        return result

    # -- inside ---------------------------------------------------------------------------

    def _path(
        self,
        planner: GlobalPlanner,
        blocked: np.ndarray,
        occupancy: np.ndarray,
        goal: Cell,
        cell: Cell,
    ) -> tuple[np.ndarray, int]:
        # The map with the dead ends blocked, a whole-map temporary (1 MB at 1000²: ~120 µs a
        # step), is built only for the steps that read more than the user's cell: a plan,
        # leaving a pocket, an escape. The planner holds the dead ends already; a plain step
        # needs only the cell.
        kept, self._kept = self._kept, None
        if (
            kept is not None
            and kept[0] is planner
            and kept[1] == cell
            and kept[2] == goal
            and self._planned
            and self._pending is None
            and self._leaving is None
        ):
            # Nothing reached the planner since (every change, plan, escape or pocket clears
            # it): its path from the same cell is the one read last step.
            self._kept = kept
            self.report.max_open = getattr(planner, "max_open", None)
            return kept[3], kept[4]
        dead = self.dead
        if dead is not None and (not self._planned or self._leaving is not None or dead[cell]):
            blocked, dead = blocked | dead, None
        if not self._planned:
            self._record(planner.plan(blocked, goal))
            self._planned, self._pending, self.report.planned = True, None, True
        if self._leaving is not None:
            blocked = self._left_pocket(planner, blocked, goal, cell)
        if blocked[cell]:
            if self._pending is not None:
                self._record(planner.update(*self._take()))
            whole = blocked if dead is None else blocked | dead
            return self._escape(planner, whole, occupancy, cell, goal)
        searched = None
        if self._pending is None:
            path = planner.path(cell)
            # A planner that searches at every path read (A*) says what that search cost.
            searched = getattr(planner, "search_stats", None)
            if searched is not None:
                self._record(searched)
        else:  # a walking step: _take and _record written out (a frame each, every step)
            (flipped, now), self._pending = self._pending, None
            stats, path = planner.update_and_path(flipped, now, cell)
            self.report.stats = stats
        self.report.max_open = getattr(planner, "max_open", None)
        if len(path) == 0:
            # A free pocket the margin closes in (a user who stepped between obstacles the
            # sensor saw late): the way out is the same as from inside the margin.
            whole = blocked if dead is None else blocked | dead
            return self._escape(planner, whole, occupancy, cell, goal)
        # The path's own cost is g at the user's cell (the path descends g by each step's cost
        # to the goal's 0); summed on the host, it costs no device round trip.
        cost = path_cost(path)
        if searched is None and self._leaving is None and (dead is None or not dead[cell]):
            self._kept = (planner, cell, goal, path, cost)  # a search per read is not kept
        return path, cost

    def _escape(
        self,
        planner: GlobalPlanner,
        blocked: np.ndarray,
        occupancy: np.ndarray,
        cell: Cell,
        goal: Cell,
    ) -> tuple[np.ndarray, int]:
        """The way out to the nearest usable cell within the margin's reach, else within
        three times it: a user who wandered between obstacles (or a pocket as wide as the
        margin) is led back out rather than told there is no path."""
        path, cost = escape_path(planner, blocked, occupancy, cell, self._escape_reach)
        if len(path) == 0:
            path, cost = escape_path(planner, blocked, occupancy, cell, 3 * self._escape_reach)
        if len(path) == 0:  # a pocket: back the way the user came
            path, cost, lead = track_out(planner, blocked, occupancy, self.track)
            if len(path):
                self.report.back_along_track = True
                # Every lead of the way out: the first may be short (the pocket found late).
                band = dead_end_of(lead, occupancy, self._radius)
                self._leaving = band if self._leaving is None else self._leaving | band
        if len(path) == 0 and self._may_narrow:
            path, cost = self._narrower(occupancy, goal, cell)
        return path, cost

    def _narrower(self, occupancy: np.ndarray, goal: Cell, cell: Cell) -> tuple[np.ndarray, int]:
        """The last resort before NO_PATH: the map inflated by one cell less (``NARROWER_CELLS``).
        A camera's obstacles bleed a cell into the free space beside their faces (range
        noise), so the full margin can close a passage the user fits through; a smaller
        one still never enters a known obstacle or the cells next to it, and the STOP
        before contact stays. Planned afresh on the CPU each step it is needed."""
        for radius in range(self._radius - 1, max(0, self._radius - 1 - NARROWER_CELLS), -1):
            narrow = InflatedMap(occupancy, radius).blocked
            if self.dead is not None:
                narrow = narrow | self.dead
            if narrow[goal]:
                continue
            planner = self._factory("cpu")
            planner.plan(narrow, goal)
            if narrow[cell]:
                path, cost = escape_path(planner, narrow, occupancy, cell, self._escape_reach)
            else:
                path = planner.path(cell)
                cost = path_cost(path) if len(path) else int(INF)
            if len(path):
                self.report.narrower_cells = radius
                return path, cost
        return np.empty((0, 2), np.int32), int(INF)

    def _left_pocket(
        self, planner: GlobalPlanner, blocked: np.ndarray, goal: Cell, cell: Cell
    ) -> np.ndarray:
        """Once the user stands clear of the way they were led out of a pocket, that way is
        a dead end: blocked for the planner from now on (this goal). Returns the blocked
        map the planner now holds."""
        band = self._leaving
        assert band is not None
        if band[cell]:
            return blocked  # still on the way out
        self._leaving = None
        band[goal] = False
        new = np.flatnonzero((band & ~blocked).reshape(-1))
        self.dead = band if self.dead is None else self.dead | band
        if new.size:
            if self._pending is not None:
                self._record(planner.update(*self._take()))
            self._record(planner.update(new, np.ones(new.size, bool)))
        return blocked | band

    def _take(self) -> tuple[np.ndarray, np.ndarray]:
        pending, self._pending = self._pending, None
        assert pending is not None
        return pending

    def _record(self, stats: UpdateStats) -> None:
        self.report.stats = stats

    def _guarded(self, call: Callable[[GlobalPlanner], object], retry: bool):
        """``call(planner)``; on a device error, the rest of the session on the CPU, where the
        call is asked again (``retry``) or left to the next path read, which plans afresh."""
        try:
            return call(self.planner)
        except self._errors as exc:
            self._fall_back(exc)
            return call(self.planner) if retry else None

    def _fall_back(self, exc: BaseException) -> None:
        """The rest of the session on a CPU planner, which plans afresh at the next call."""
        self.fallback_reason = f"{type(exc).__name__}: {exc}"
        log.warning("planner failed on the device (%s); this user continues on the CPU",
                    self.fallback_reason)  # fmt: skip
        self.planner = self._factory("cpu")
        self.invalidate()
