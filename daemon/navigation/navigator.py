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
from collections.abc import Callable
from dataclasses import replace

import numpy as np

from daemon.guidance.guide import Guidance
from daemon.planning.grid import Cell, cell_to_xy, in_bounds, xy_to_cell
from daemon.planning.inflation import radius_in_cells
from daemon.planning.registry import make_planner
from protocol.messages import Goal, NavState, NavStatus, PatternKind, Pose, StatusCode

from .clear_way import keep_clear
from .controls import UserControls, Whereabouts
from .goals import goal_cell
from .inbox import Inbox, StepOutput
from .log_limit import LogLimiter
from .map_keeper import MapKeeper, MapUpdate
from .outcomes import OUTCOMES, Rejection
from .pose_margin import PoseMargin
from .proximity import ProximityGuard, ProximitySettings
from .route import PlannerFactory, Route
from .session_state import SessionState
from .settings import NavigatorSettings, StepReport

log = logging.getLogger("guidebelt.navigation")

OK = StatusCode.OK
STATUS_REFRESH_S = 1.0
FUTURE_SKEW_S = 0.5
"""A pose stamped further ahead of the daemon's clock than this is refused: a clock that far
off is no clock, and such a pose would never go stale."""
ESCAPE_MARGIN_CELLS = 2
"""How far beyond the inflation radius a way out of the margin is looked for."""


class Navigator:
    def __init__(
        self,
        user: str,
        settings: NavigatorSettings,
        *,
        guidance: Guidance | None = None,
        planner_factory: PlannerFactory | None = None,
        map_cells: Callable[[int], None] | None = None,
    ) -> None:
        """``planner_factory(backend)`` overrides the registry (tests inject failing planners);
        ``map_cells(cells)`` is told each new map's size (``MapKeeper``'s ``on_cells``)."""
        self.user = user
        self.settings = settings
        self.radius_cells = radius_in_cells(settings.user_radius_m, settings.cell_m)
        self.maps = MapKeeper(self.radius_cells, map_cells)
        self.margin = PoseMargin(settings.cell_m, self.radius_cells)
        self.route = Route(
            planner_factory
            or (lambda backend: make_planner(settings.planner, backend, settings.variant)),
            settings.backend,
            self.radius_cells + ESCAPE_MARGIN_CELLS,
            self.radius_cells,
        )
        # Guidance may shave the inflation margin; it must know the real radius.
        self.guidance = guidance or Guidance(
            cell_m=settings.cell_m, lang=settings.lang, radius_m=settings.user_radius_m,
            arrive_m=settings.arrive_m, voice=settings.voice, wording=settings.wording,
            units=settings.units, reassure_s=settings.reassure_s,
        )  # fmt: skip
        # Smoothing (when guidance is asked for it) takes the model of the planner in use.
        self.guidance.planner = lambda: self.route.planner
        self.guidance.patterns.map_seq = lambda: self.maps.seq  # each names the map it was on
        self.goal: Goal | None = None
        self.goal_cell: Cell | None = None
        self.pose: Pose | None = None
        self.pose_received = 0.0
        """When the daemon received ``pose`` (its clock): staleness is judged on this."""
        self.pose_cell: Cell | None = None
        self._pose_stamp: float | None = None
        self._pose_before: float | None = None
        """The stamp of the pose before the latest: the camera must have looked since."""
        self._last_path_flat = np.empty(0, np.int64)
        self.session = SessionState()
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
        self._taken_at = 0.0
        self._shed = self._behind = False
        self.controls = UserControls(
            settings.lang,  # type: ignore[arg-type]  # validated by the config
            settings.intensity,
            settings.battery,
        )

    @property
    def state(self) -> NavState:
        return self.session.state

    @property
    def rejected(self) -> int:  # refused inputs, all codes
        return sum(self.rejected_by_code.values())

    # -- the step -------------------------------------------------------------------------

    def step(self, inbox: Inbox, now: float) -> StepOutput:
        t0 = time.perf_counter()
        self.last = StepReport()
        self.session.begin_step()  # a STOP or WAIT of this step is not undone by this step
        self._taken_at = inbox.taken_at if inbox.taken_at is not None else now
        self._shed, self._behind = inbox.overloaded, inbox.daemon_behind or inbox.pose_unread
        out = StepOutput()
        if self._shed:  # said first: nothing later in this step may guide
            why = "the daemon is at capacity: guidance paused"
            self._reject(Rejection(StatusCode.OVERLOADED, why, counted=False), now, out)
        if (asked := inbox.settings) is not None:  # this step's words in the user's choice
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
            self.route.forget_dead_ends()
            self.guidance.reset()
            self._set_state(NavState.PLANNING, OK, "goal received", now, out, force=True)
        if self.goal is not None and self.goal_cell is None and self.maps.map is not None:
            self._resolve_goal(now, out)
        if inbox.pose is not None:
            received = inbox.pose_received if inbox.pose_received is not None else now
            self._take_pose(inbox.pose, received, now, out)
        elif self.pose is not None and self.pose_cell is None and self.maps.map is not None:
            self._take_pose(self.pose, self.pose_received, now, out)  # it came before the map
        if self.safety.step(inbox.proximity, now, self.guidance, out, self.goal_cell is not None):
            self.session.hold()  # an obstacle at arm's length: no GUIDE in this step
        if self.maps.map is not None and self.goal_cell is not None and self.pose_cell is not None:
            if self.maps.stale:
                self._wait_for_map(now, out)
            elif (
                self.session.may_guide()
                and self.safety.looked_since(self._pose_before, now)  # else: the frame guides
                and not self._pose_unsure(now, out)
            ):
                self._guide(now, out)
        elif self.pose is None and self.pose_received and self.goal_cell is not None:
            self._pose_missing(now, out)
        # After a STOP before contact, no GUIDE back into what the camera saw (an estimated pose
        # may be off by more than the margin).
        self.safety.blocked.steer(inbox.proximity, self.pose, now, self.guidance, out)
        if self.controls.finish(inbox, out, now, self.guidance, self._whereabouts()):
            why = "guidance paused by the user" if self.controls.paused else "guidance resumed"
            self._set_state(self.state, OK, why, now, out, force=True)
        if not self._shed:  # a shed user's planner is rebuilt when they are guided again
            self.route.settle()  # no path read this step: the planner still gets the changes
        self.steps += 1
        self.last.step_ms = (time.perf_counter() - t0) * 1e3
        return out

    def between_steps(self) -> None:
        """Once the step's outputs are out: what the planner left for then (``idle_ms``)."""
        t0 = time.perf_counter()
        self.route.between_steps()
        self.last.idle_ms = (time.perf_counter() - t0) * 1e3

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
            goal_xy = cell_to_xy(self.maps.map.shape, self.goal_cell, self.settings.cell_m)
        return Whereabouts(self.pose, goal_xy, self._distance_m, self._turn_xy)

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
            if self._shed:
                self.route.invalidate()  # no planning for a shed user: plan afresh later
            else:
                self.route.change(update.flipped, update.blocked_now)

    def _resolve_goal(self, now: float, out: StepOutput) -> None:
        assert self.maps.map is not None and self.goal is not None
        where = goal_cell(self.goal, self.maps.map, self.settings.cell_m, self.settings.landmarks)
        if isinstance(where, Rejection):
            self.goal, self.goal_cell = None, None
            self.route.invalidate()
            return self._reject(where, now, out)
        self.goal_cell = where

    def _take_pose(self, pose: Pose, received: float, now: float, out: StepOutput) -> None:
        if pose.stamp != self._pose_stamp:
            self._pose_before, self._pose_stamp = self._pose_stamp, pose.stamp
        self.pose, self.pose_cell = None, None
        age = received - pose.stamp
        if age > self.settings.stale_pose_s or -age > FUTURE_SKEW_S:
            # Judged when it arrived: a pose already old then, or from the future (it would
            # never go stale), is no position to guide on.
            ahead = f"pose is {-age:.2f} s ahead of the daemon's clock"
            why = f"pose was {age:.2f} s old when it arrived" if age > 0 else ahead
            return self._reject(Rejection(StatusCode.STALE_POSE, why), now, out)
        self.pose, self.pose_received = pose, received
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
        if not self.session.may_guide():
            return  # this step said WAIT or STOP already
        out.belt.append(self.guidance.event(PatternKind.WAIT, now, "map out of date").pattern)

    def _pose_unsure(self, now: float, out: StepOutput) -> bool:
        """Obstacles enlarged by ω/2 + a, a from the pose's uncertainty; WAIT past a limit."""
        assert self.pose is not None
        if self.margin.too_unsure(self.pose):
            why = f"pose quality {self.pose.quality:.2f} (sigma {self.pose.sigma_m} m)"
            self._reject(Rejection(StatusCode.POSE_UNCERTAIN, why, counted=False), now, out)
            return True
        self.guidance.arrive_m = self.margin.arrive_within_m(self.settings.arrive_m)
        no_way = self.state == NavState.NO_PATH
        self.last.changed += self.margin.adjust(self.maps, self.route, self.goal_cell, now, no_way)
        return False

    def _pose_missing(self, now: float, out: StepOutput) -> None:
        """No pose since one was dropped (stale, or unread while the daemon was behind): past
        ``stale_pose_s`` the cause is said as it is now, once, so a localiser that died is
        never reported as the daemon's backlog."""
        age = self._taken_at - self.pose_received
        if age <= self.settings.stale_pose_s or self._shed:
            return
        code = StatusCode.OVERLOADED if self._behind else StatusCode.STALE_POSE
        if self._last_status is None or self._last_status[1] != code:
            self._reject(Rejection(code, f"no pose for {age:.2f} s", counted=False), now, out)

    def _guide(self, now: float, out: StepOutput) -> None:
        grid = self.maps.map
        assert grid is not None and self.goal_cell is not None and self.pose_cell is not None
        assert self.pose is not None
        # Against when the step's inputs were taken, on the daemon's clock: a step the daemon
        # was slow to run does not make the user's localiser silent.
        age = self._taken_at - self.pose_received
        if age > self.settings.stale_pose_s:
            # No fresh position: never keep guiding on an old one.
            self.pose, self.pose_cell = None, None
            why = f"no pose for {age:.2f} s"
            if self._behind:  # the daemon's own backlog may have kept the poses from us
                rej = Rejection(StatusCode.OVERLOADED, f"{why}, the daemon behind", counted=False)
                return self._reject(rej, now, out)
            return self._reject(Rejection(StatusCode.STALE_POSE, why), now, out)
        # Less clearance than the user's radius only when the pose adds no margin of its own.
        path, cost = self.route.path_from(grid.blocked, grid.occupancy, self.goal_cell,
                                          self.pose_cell, self.margin.extra_cells == 0)  # fmt: skip
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
        g = self.guidance.guide(path, self.pose, grid.shape, now, blocked=grid.blocked,
                                occupancy=grid.occupancy, map_version=grid.version)  # fmt: skip
        self.last.guide_ms = (time.perf_counter() - t0) * 1e3
        # From where the user really stands, not the cell's centre: never past a known corner.
        safe = keep_clear(g.pattern, self.pose, g.target, grid.occupancy, self.settings.cell_m)
        if safe is not None:
            g = replace(g, pattern=safe)
            self.guidance.hysteresis.reset()  # the next direction is felt from this one
        # After a STOP's hold: around what the frame shows ahead, which the map may not hold.
        around = self.safety.lead_around(g.pattern, self.pose, grid.occupancy,
                                         self.settings.cell_m, self.guidance, now)  # fmt: skip
        if around is not None:
            g = replace(g, pattern=around)
            self.guidance.hysteresis.reset()
        out.belt.append(g.pattern)
        if g.cue is not None:
            out.voice.append(g.cue)
        self._turn_xy = g.target
        out.path_cells = path
        out.path_meta = dict(cost=cost, cell_m=self.settings.cell_m, height=grid.shape[0],
                             width=grid.shape[1], pose_stamp=self.pose.stamp, stamp=now,
                             map_seq=self.maps.seq)  # fmt: skip
        if g.pattern.kind == PatternKind.ARRIVED:
            self._set_state(NavState.ARRIVED, OK, "at the goal", now, out)
            self.goal, self.goal_cell = None, None  # done: stay quiet until the next goal
            self.route.invalidate()
        elif g.pattern.kind == PatternKind.REROUTE:
            self._set_state(NavState.REROUTING, OK, "new path around an obstacle", now, out)
        else:
            why = self.last.plan.way_out(self.settings.cell_m)  # "" on the plain path
            self._set_state(NavState.GUIDING, OK, why, now, out)

    # -- reporting ------------------------------------------------------------------------

    def _reject(self, rej: Rejection, now: float, out: StepOutput) -> None:
        outcome = OUTCOMES[rej.code]
        if outcome.pattern in (PatternKind.STOP, PatternKind.WAIT):
            self.session.hold()
        if rej.counted:
            self.rejected_by_code[rej.code] = self.rejected_by_code.get(rej.code, 0) + 1
        self.log_limit.refusal(log, self.user, str(rej.code), rej.reason, rej.counted)
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
        self.session.move(state)  # raises on a move the session does not allow
        key = (state, code, reason)
        if not force and key == self._last_status and now - self._last_status_at < STATUS_REFRESH_S:
            return
        self._last_status = key
        self._last_status_at = now
        out.statuses.append(self.status(now, code=code, reason=reason))

    def status(self, now: float, code: StatusCode = StatusCode.OK, reason: str = "") -> NavStatus:
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
