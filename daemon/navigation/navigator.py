"""One user's navigation: map, inflation, planner, goal, pose, path and guidance.

``Navigator.step`` takes everything that arrived for the user since the last step (an
``Inbox``: map deltas or a snapshot, the latest pose, a goal, refusals, a clock tick) and
returns what to tell the user (a ``StepOutput``: belt patterns, voice cues, the path, status).
The daemon wraps one navigator per user with zenoh; every simulated walk and the benchmark
drive the same class, so what they measure is what the daemon does. Nothing here knows about
zenoh, threads or asyncio.

A step, top to bottom: refusals → map (``MapKeeper``: sequence, resync, inflation) → goal →
pose → path (``Route``: planner, repair, escape, CPU fallback) → guidance → status.
"""

from __future__ import annotations

import logging
import time
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Literal

import numpy as np

from daemon.guidance.guide import Guidance
from daemon.planning.grid import Cell, in_bounds, xy_to_cell
from daemon.planning.inflation import radius_in_cells
from daemon.planning.registry import make_planner
from protocol.messages import (
    Goal,
    GoalCell,
    GoalLandmark,
    GoalMetres,
    MapSnapshot,
    NavState,
    NavStatus,
    PatternKind,
    Pose,
    StatusCode,
)

from .controls import BatteryPolicy, UserControls, Whereabouts
from .inbox import Inbox, StepOutput
from .log_limit import LogLimiter
from .map_keeper import MapKeeper, MapUpdate
from .outcomes import OUTCOMES, Rejection
from .proximity import ProximityGuard, ProximitySettings
from .route import PlannerFactory, PlanReport, Route

log = logging.getLogger("guidebelt.navigation")

OK = StatusCode.OK
STATUS_REFRESH_S = 1.0
ESCAPE_MARGIN_CELLS = 2
"""How far beyond the inflation radius a way out of the margin is looked for."""


@dataclass(frozen=True)
class NavigatorSettings:
    """What one user's navigation needs to know; the daemon's config supplies it."""

    planner: str = "eds"
    backend: str = "auto"
    variant: str = "fast"
    cell_m: float = 0.10
    user_radius_m: float = 0.3
    lang: str = "en"
    stale_pose_s: float = 1.0
    arrive_m: float = 0.3
    voice: Literal["companion", "sole"] = "companion"
    """``sole``: the voice guides alone (no belt); it speaks more and stops before contact."""
    wording: Literal["clock", "sides"] = "clock"
    units: Literal["metric", "imperial"] = "metric"
    reassure_s: float = 15.0
    landmarks: Mapping[str, tuple[float, float]] = field(default_factory=dict)
    intensity: int = 100
    battery: BatteryPolicy = field(default_factory=BatteryPolicy)
    stop_m: float = 0.6
    """An obstacle nearer than this ahead in the camera's latest frame: STOP (``proximity``)."""


@dataclass(slots=True)
class StepReport:
    """How long the last step took, by part, and what the planner did in it."""

    changed: int = 0
    """Cells whose blocked state flipped."""
    inflate_ms: float = 0.0
    """Applying the step's deltas to the map and inflating them."""
    plan: PlanReport = field(default_factory=PlanReport)
    guide_ms: float = 0.0
    step_ms: float = 0.0
    """The whole step, inputs to outputs."""


class Navigator:
    def __init__(
        self,
        user: str,
        settings: NavigatorSettings,
        *,
        guidance: Guidance | None = None,
        planner_factory: PlannerFactory | None = None,
    ) -> None:
        """``planner_factory(backend)`` overrides the registry (tests inject failing planners)."""
        self.user = user
        self.settings = settings
        self.radius_cells = radius_in_cells(settings.user_radius_m, settings.cell_m)
        self.maps = MapKeeper(self.radius_cells)
        self.route = Route(
            planner_factory
            or (lambda backend: make_planner(settings.planner, backend, settings.variant)),
            settings.backend,
            self.radius_cells + ESCAPE_MARGIN_CELLS,
        )
        # Guidance may shave the inflation margin; it must know the real radius.
        self.guidance = guidance or Guidance(
            cell_m=settings.cell_m, lang=settings.lang, radius_m=settings.user_radius_m,
            arrive_m=settings.arrive_m, voice=settings.voice, wording=settings.wording,
            units=settings.units, reassure_s=settings.reassure_s,
        )  # fmt: skip
        self.goal: Goal | None = None
        self.goal_cell: Cell | None = None
        self.pose: Pose | None = None
        self.pose_cell: Cell | None = None
        self._last_path_flat = np.empty(0, np.int64)
        self.state = NavState.IDLE
        self.rejected_by_code: dict[str, int] = {}
        """Refused inputs by status code, for the daemon's health (``rejected``: their sum)."""
        self.log_limit = LogLimiter()
        self.safety = ProximityGuard(ProximitySettings(stop_m=settings.stop_m))
        self.steps = 0
        self.replans = 0
        self.last = StepReport()
        self._last_status: tuple | None = None
        self._last_status_at = 0.0
        self._distance_m: float | None = None
        self._turn_xy: tuple[float, float] | None = None
        self._held = False
        self.controls = UserControls(
            settings.lang,  # type: ignore[arg-type]  # validated by the config
            settings.intensity,
            settings.battery,
        )

    @property
    def rejected(self) -> int:
        """Refused inputs, all codes."""
        return sum(self.rejected_by_code.values())

    # -- the step -------------------------------------------------------------------------

    def step(self, inbox: Inbox, now: float) -> StepOutput:
        t0 = time.perf_counter()
        self.last = StepReport()
        self._held = False  # a STOP or WAIT of this step is not undone by a GUIDE of this step
        out = StepOutput()
        if inbox.settings is not None:  # this step's words already in the user's choice
            asked = inbox.settings
            self.guidance.apply(voice=asked.voice, wording=asked.wording, units=asked.units)
        for rej in inbox.rejections:
            self._reject(rej, now, out)
        if inbox.snapshot_failed:
            self.maps.snapshot_failed()
        if inbox.snapshot is not None:
            self._take_map(self.maps.take_snapshot(inbox.snapshot, self.user), now, out)
        if inbox.deltas:
            t1 = time.perf_counter()
            update = self.maps.take_deltas(inbox.deltas)
            self.last.inflate_ms = (time.perf_counter() - t1) * 1e3
            self._take_map(update, now, out)
        if inbox.goal is not None:
            self.goal, self.goal_cell = inbox.goal, None
            self.route.invalidate()
            self.guidance.reset()
            self._set_state(NavState.PLANNING, OK, "goal received", now, out, force=True)
        if self.goal is not None and self.goal_cell is None and self.maps.map is not None:
            self._resolve_goal(now, out)
        if inbox.pose is not None:
            self._take_pose(inbox.pose, now, out)
        elif self.pose is not None and self.pose_cell is None and self.maps.map is not None:
            self._take_pose(self.pose, now, out)  # the pose came before the map
        guiding = self.goal_cell is not None
        self._held |= self.safety.step(inbox.proximity, now, self.guidance, out, guiding)
        if self.maps.map is not None and self.goal_cell is not None and self.pose_cell is not None:
            if self.maps.stale:
                self._wait_for_map(now, out)
            elif not self._held:
                self._guide(now, out)
        if self.controls.finish(inbox, out, now, self.guidance, self._whereabouts()):
            why = "guidance paused by the user" if self.controls.paused else "guidance resumed"
            self._set_state(self.state, OK, why, now, out, force=True)
        self.route.settle()  # no path read this step: the planner still gets the changes
        self.steps += 1
        self.last.step_ms = (time.perf_counter() - t0) * 1e3
        return out

    def halt(
        self, now: float, code: StatusCode = StatusCode.SHUTDOWN, reason: str = "daemon stopping"
    ) -> StepOutput:
        """A STOP (or, for an idle user, OFF) pattern and its status, touching nothing else:
        the daemon's last words to a user, and what a step that failed says instead."""
        out = StepOutput()
        self._reject(Rejection(code, reason, counted=False), now, out)
        return out

    def _whereabouts(self) -> Whereabouts:
        goal_xy = None
        if self.goal_cell is not None and self.maps.map is not None:
            r, c = self.goal_cell
            cell_m = self.settings.cell_m
            goal_xy = ((c + 0.5) * cell_m, (self.maps.map.shape[0] - r - 0.5) * cell_m)
        return Whereabouts(self.pose, goal_xy, self._distance_m, self._turn_xy)

    def snapshot(self, now: float) -> MapSnapshot | None:
        return self.maps.snapshot(now)

    # -- map, goal, pose ------------------------------------------------------------------

    def _take_map(self, update: MapUpdate, now: float, out: StepOutput) -> None:
        for rej in update.rejections:
            self._reject(rej, now, out)
        out.want_snapshot |= update.want_snapshot
        if update.new_map:
            self.route.invalidate()
            if self.goal is not None:
                self.goal_cell = None  # checked again against the new map
        if update.flipped is not None and update.flipped.size:
            assert self.maps.map is not None
            self.last.changed += int(update.flipped.size)
            if self.maps.map.blocked.reshape(-1)[self._last_path_flat].any():
                self.replans += 1  # a newly seen obstacle cut the path the user was following
            self.route.change(update.flipped, update.blocked_now)

    def _resolve_goal(self, now: float, out: StepOutput) -> None:
        assert self.maps.map is not None and self.goal is not None
        target, shape, cell_m = self.goal.target, self.maps.map.shape, self.settings.cell_m
        if isinstance(target, GoalCell):
            cell = (target.row, target.col)
        elif isinstance(target, GoalMetres):
            cell = xy_to_cell(shape, target.x, target.y, cell_m)
        elif isinstance(target, GoalLandmark):
            where = self.settings.landmarks.get(target.name)
            if where is None:
                why = f"no landmark {target.name!r}"
                return self._drop_goal(StatusCode.UNKNOWN_LANDMARK, why, now, out)
            cell = xy_to_cell(shape, where[0], where[1], cell_m)
        if not in_bounds(shape, cell):
            why = f"goal cell {cell} is outside {shape}"
            return self._drop_goal(StatusCode.GOAL_OFF_MAP, why, now, out)
        if self.maps.map.blocked[cell]:
            what = "an obstacle" if self.maps.map.occupancy[cell] == 1 else "too close to one"
            why = f"goal cell {cell} is {what}"
            return self._drop_goal(StatusCode.GOAL_IN_OBSTACLE, why, now, out)
        self.goal_cell = (int(cell[0]), int(cell[1]))

    def _drop_goal(self, code: StatusCode, reason: str, now: float, out: StepOutput) -> None:
        self.goal, self.goal_cell = None, None
        self.route.invalidate()
        self._reject(Rejection(code, reason), now, out)

    def _take_pose(self, pose: Pose, now: float, out: StepOutput) -> None:
        self.pose, self.pose_cell = None, None
        age = now - pose.stamp
        if abs(age) > self.settings.stale_pose_s:
            # A pose from the future would never go stale: a clock that far off is no clock.
            why = f"pose is {age:.2f} s old" if age > 0 else f"pose is {-age:.2f} s ahead"
            return self._reject(Rejection(StatusCode.STALE_POSE, why), now, out)
        self.pose = pose
        if self.maps.map is None:
            return
        cell = xy_to_cell(self.maps.map.shape, pose.x, pose.y, self.settings.cell_m)
        if not in_bounds(self.maps.map.shape, cell):
            self.pose = None
            where = f"({pose.x:.2f}, {pose.y:.2f}) m"
            why = f"pose {where} is off the map"
            return self._reject(Rejection(StatusCode.POSE_OFF_MAP, why), now, out)
        self.pose_cell = cell

    # -- path and guidance ----------------------------------------------------------------

    def _wait_for_map(self, now: float, out: StepOutput) -> None:
        """Deltas are missing: the map is out of date, so the belt keeps saying WAIT (and its
        pattern keeps being refreshed) until a snapshot brings the map back."""
        if self._held:
            return  # this step said WAIT or STOP already
        g = self.guidance.event(PatternKind.WAIT, now, reason="map out of date")
        out.belt.append(g.pattern)

    def _guide(self, now: float, out: StepOutput) -> None:
        grid = self.maps.map
        assert grid is not None and self.goal_cell is not None and self.pose_cell is not None
        assert self.pose is not None
        age = now - self.pose.stamp
        if abs(age) > self.settings.stale_pose_s:
            # No fresh position: never keep guiding on an old one.
            self.pose, self.pose_cell = None, None
            why = f"no pose for {age:.2f} s"
            return self._reject(Rejection(StatusCode.STALE_POSE, why), now, out)
        path, cost = self.route.path_from(
            grid.blocked, grid.occupancy, self.goal_cell, self.pose_cell
        )
        self.last.plan = self.route.report
        self._last_path_flat = path[:, 0].astype(np.int64) * grid.shape[1] + path[:, 1]
        if len(path) == 0:
            self._distance_m = None
            if self.state != NavState.NO_PATH:
                no_path = Rejection(StatusCode.NO_PATH, "no path to the goal", counted=False)
                self._reject(no_path, now, out)
            else:  # said already: the belt keeps showing it (its pattern expires), no new words
                out.belt.append(self.guidance.patterns.event(PatternKind.NO_PATH, now))
            return
        self._distance_m = cost / 10 * self.settings.cell_m
        t0 = time.perf_counter()
        g = self.guidance.guide(
            path, self.pose, grid.shape, now, blocked=grid.blocked, occupancy=grid.occupancy
        )
        self.last.guide_ms = (time.perf_counter() - t0) * 1e3
        out.belt.append(g.pattern)
        if g.cue is not None:
            out.voice.append(g.cue)
        self._turn_xy = g.target
        out.path_cells = path
        out.path_meta = dict(
            cost=cost,
            cell_m=self.settings.cell_m,
            height=grid.shape[0],
            width=grid.shape[1],
            pose_stamp=self.pose.stamp,
            stamp=now,
            map_seq=self.maps.seq,
        )
        if g.pattern.kind == PatternKind.ARRIVED:
            self._set_state(NavState.ARRIVED, OK, "at the goal", now, out)
            self.goal, self.goal_cell = None, None  # done: stay quiet until the next goal
            self.route.invalidate()
        elif g.pattern.kind == PatternKind.REROUTE:
            self._set_state(NavState.REROUTING, OK, "new path around an obstacle", now, out)
        else:
            self._set_state(NavState.GUIDING, OK, "", now, out)

    # -- reporting ------------------------------------------------------------------------

    def _reject(self, rej: Rejection, now: float, out: StepOutput) -> None:
        outcome = OUTCOMES[rej.code]
        self._held |= outcome.pattern in (PatternKind.STOP, PatternKind.WAIT)
        if rej.counted:
            self.rejected_by_code[rej.code] = self.rejected_by_code.get(rej.code, 0) + 1
        held = self.log_limit.allow(str(rej.code), time.monotonic())
        if held is not None:
            fields = {"user": self.user, "code": rej.code, "reason": rej.reason}
            if held:
                fields["suppressed"] = held  # lines of this code held back since the last
            log.log(
                logging.WARNING if rej.counted else logging.INFO,
                "rejected" if rej.counted else rej.code,
                extra={"fields": fields},
            )
        g = self.guidance.event(outcome.pattern, now, reason=rej.code)
        out.belt.append(g.pattern)
        if g.cue is not None:
            out.voice.append(g.cue)
        self._set_state(outcome.state, rej.code, rej.reason, now, out, force=True)

    def _set_state(
        self,
        state: NavState,
        code: StatusCode,
        reason: str,
        now: float,
        out: StepOutput,
        force: bool = False,
    ) -> None:
        key = (state, code, reason)
        if not force and key == self._last_status and now - self._last_status_at < STATUS_REFRESH_S:
            self.state = state
            return
        self.state = state
        self._last_status = key
        self._last_status_at = now
        out.statuses.append(self.status(now, code=code, reason=reason))

    def status(
        self, now: float, code: StatusCode = StatusCode.OK, reason: str = ""
    ) -> NavStatus:
        if self._last_status is not None and not code and not reason:
            _, code, reason = self._last_status
        guiding = self.state in (NavState.GUIDING, NavState.REROUTING)
        return NavStatus(
            state=self.state,
            reason=reason,
            code=code,
            stamp=now,
            distance_m=self._distance_m if guiding else None,
            rejected=self.rejected,
            replans=self.replans,
            backend=self.route.name,
            paused=self.controls.paused,
        )
