"""One user's navigation: map, planner, goal, pose and guidance, stepped on one worker thread.

The loop thread only fills an ``Inbox``; ``UserSession.step`` takes a whole inbox at once,
so the latest pose wins and every delta that arrived since the last step is applied in
one ``InflatedMap.apply`` and one EDS update, made with the step's path read in one
``update_and_path`` call (one GPU round trip). Nothing here knows about zenoh or asyncio:
``step`` returns the messages to publish.
"""

from __future__ import annotations

import logging
import time
from collections.abc import Callable

import numpy as np

from daemon.planning import GlobalPlanner, make_planner
from daemon.planning.escape import escape_path
from daemon.planning.grid import INF, UNKNOWN, in_bounds, xy_to_cell
from daemon.planning.inflation import InflatedMap, radius_in_cells
from protocol.messages import (
    Goal,
    GoalCell,
    GoalLandmark,
    GoalMetres,
    MapDelta,
    MapSnapshot,
    NavState,
    NavStatus,
    PatternKind,
    Pose,
)

from .config import DaemonConfig
from .inbox import Inbox, StepOutput
from .rejections import OUTCOMES, Rejection

log = logging.getLogger("guidebelt.session")

MAX_BUFFERED_DELTAS = 256
"""Deltas kept while a snapshot is on its way; more means the snapshot is hopeless."""
STATUS_REFRESH_S = 1.0


class UserSession:
    def __init__(
        self,
        user: str,
        config: DaemonConfig,
        planner_factory: Callable[[], GlobalPlanner] | None = None,
        guidance_factory: Callable[[], object] | None = None,
    ) -> None:
        self.user = user
        self.config = config
        self._make_planner = planner_factory or (
            lambda: make_planner("eds", config.backend, config.variant)
        )
        self.planner = self._make_planner()
        if guidance_factory is None:
            from daemon.guidance.guide import Guidance

            def guidance_factory() -> Guidance:
                # Guidance may shave the inflation margin; it must know the real radius.
                return Guidance(
                    cell_m=config.cell_m, lang=config.lang, radius_m=config.user_radius_m
                )
        self.guidance = guidance_factory()
        self.radius_cells = radius_in_cells(config.user_radius_m, config.cell_m)

        self.map: InflatedMap | None = None
        self.map_seq = -1
        self.resyncing = False
        self._buffered: dict[int, MapDelta] = {}
        self.goal: Goal | None = None
        self.goal_cell: tuple[int, int] | None = None
        self._planned = False
        self.pose: Pose | None = None
        self.pose_cell: tuple[int, int] | None = None
        self._last_path_flat = np.empty(0, np.int64)
        self._pending: tuple[np.ndarray, np.ndarray] | None = None
        """Changes not yet given to the planner: the step's path read takes them along."""

        self.state = NavState.IDLE
        self.rejected = 0
        self.steps = 0
        self.replans = 0
        self.last_step_ms = 0.0
        self._last_status: tuple | None = None
        self._last_status_at = 0.0
        self._distance_m: float | None = None

    # -- the step -------------------------------------------------------------------------

    def step(self, inbox: Inbox, now: float) -> StepOutput:
        t0 = time.perf_counter()
        out = StepOutput()
        for rej in inbox.rejections:
            self._reject(rej, now, out)
        if inbox.snapshot_failed:
            # Let the next delta notice the gap again and ask once more.
            self.resyncing = False
            self._buffered.clear()
        if inbox.snapshot is not None:
            self._apply_snapshot(inbox.snapshot, now, out)
        if inbox.deltas:
            self._take_deltas(inbox.deltas, now, out)
        if inbox.goal is not None:
            self.goal = inbox.goal
            self.goal_cell = None
            self._planned = False
            if hasattr(self.guidance, "reset"):
                self.guidance.reset()
            self._set_state(NavState.PLANNING, "", "goal received", now, out, force=True)
        if self.goal is not None and self.goal_cell is None and self.map is not None:
            self._resolve_goal(now, out)
        if inbox.pose is not None:
            self._take_pose(inbox.pose, now, out)
        elif self.pose is not None and self.pose_cell is None and self.map is not None:
            self._take_pose(self.pose, now, out)  # the pose came before the map
        if self.map is not None and self.goal_cell is not None and self.pose_cell is not None:
            self._guide(now, out)
        self._flush_pending()  # no path read this step
        self.steps += 1
        self.last_step_ms = (time.perf_counter() - t0) * 1e3
        return out

    def shutdown(
        self, now: float, code: str = "shutdown", reason: str = "daemon stopping"
    ) -> StepOutput:
        """The last words: a STOP (or, for an idle user, OFF) pattern and a final status."""
        out = StepOutput()
        self._reject(Rejection(code, reason, counted=False), now, out)
        return out

    def snapshot(self, now: float) -> MapSnapshot | None:
        if self.map is None:
            return None
        return MapSnapshot.from_array(max(self.map_seq, 0), self.map.occupancy, now)

    # -- map ------------------------------------------------------------------------------

    def _take_deltas(self, deltas: list[MapDelta], now: float, out: StepOutput) -> None:
        cells: list[np.ndarray] = []
        values: list[np.ndarray] = []
        for d in deltas:
            shape = (d.height, d.width)
            if self.map is None and d.seq == 0 and not self.resyncing:
                self.map = InflatedMap(np.full(shape, UNKNOWN, np.uint8), self.radius_cells)
                self._planned = False
            elif self.map is None:
                self._gap(f"first delta seen is {d.seq}, not 0", d, now, out)
                continue
            if shape != self.map.shape:
                self._reject(
                    Rejection("shape_mismatch", f"delta for {shape}, map is {self.map.shape}"),
                    now,
                    out,
                )
                out.want_snapshot = self.resyncing = True
                continue
            if self.resyncing:
                self._buffer(d)
            elif d.seq <= self.map_seq:
                continue  # already in the map (replayed, or older than a snapshot)
            elif d.seq != self.map_seq + 1:
                self._gap(f"expected delta {self.map_seq + 1}, got {d.seq}", d, now, out)
            else:
                cells.append(d.cell_array())
                values.append(d.value_array())
                self.map_seq = d.seq
        if cells:
            self._apply_cells(np.concatenate(cells), np.concatenate(values))

    def _gap(self, reason: str, d: MapDelta, now: float, out: StepOutput) -> None:
        if not self.resyncing:
            self._reject(Rejection("sequence_gap", reason + "; asking for a snapshot"), now, out)
        self.resyncing = True
        out.want_snapshot = True
        self._buffer(d)

    def _buffer(self, d: MapDelta) -> None:
        if len(self._buffered) < MAX_BUFFERED_DELTAS:
            self._buffered[d.seq] = d

    def _apply_cells(self, cells: np.ndarray, values: np.ndarray) -> None:
        assert self.map is not None
        flipped, blocked_now = self.map.apply(cells, values)
        if not flipped.size or not self._planned:
            return
        if self.map.blocked.reshape(-1)[self._last_path_flat].any():
            self.replans += 1  # a newly seen obstacle cut the path the user was following
        self._flush_pending()  # a second batch in one step (rare): hand over the first
        self._pending = (flipped, blocked_now)

    def _flush_pending(self) -> None:
        pending, self._pending = self._pending, None
        if pending is not None and self._planned:  # unplanned: the next plan includes it
            self.planner.update(*pending)

    def _path(self, cell: tuple[int, int]) -> np.ndarray:
        """The path from ``cell``, with the pending changes in the same planner call."""
        pending, self._pending = self._pending, None
        if pending is None:
            return self.planner.path(cell)
        return self.planner.update_and_path(*pending, cell)[1]

    def _apply_snapshot(self, snap: MapSnapshot, now: float, out: StepOutput) -> None:
        self.map = InflatedMap(snap.array(), self.radius_cells)
        self.map_seq = snap.seq
        self.resyncing = False
        self._planned = False
        if self.goal is not None:
            self.goal_cell = None  # re-checked against the new map
        buffered = sorted(self._buffered.values(), key=lambda d: d.seq)
        self._buffered.clear()
        log.info(
            "map resynchronised",
            extra={"fields": {"user": self.user, "seq": snap.seq, "replay": len(buffered)}},
        )
        if buffered:
            self._take_deltas(buffered, now, out)

    # -- goal and pose --------------------------------------------------------------------

    def _resolve_goal(self, now: float, out: StepOutput) -> None:
        assert self.map is not None and self.goal is not None
        target = self.goal.target
        shape = self.map.shape
        if isinstance(target, GoalCell):
            cell = (target.row, target.col)
        elif isinstance(target, GoalMetres):
            cell = xy_to_cell(shape, target.x, target.y, self.config.cell_m)
        elif isinstance(target, GoalLandmark):
            where = self.config.landmarks.get(target.name)
            if where is None:
                return self._drop_goal("unknown_landmark", f"no landmark {target.name!r}", now, out)
            cell = xy_to_cell(shape, where[0], where[1], self.config.cell_m)
        if not in_bounds(shape, cell):
            return self._drop_goal("goal_off_map", f"goal cell {cell} is outside {shape}", now, out)
        if self.map.blocked[cell]:
            what = "an obstacle" if self.map.occupancy[cell] == 1 else "too close to an obstacle"
            return self._drop_goal("goal_in_obstacle", f"goal cell {cell} is {what}", now, out)
        self.goal_cell = (int(cell[0]), int(cell[1]))

    def _drop_goal(self, code: str, reason: str, now: float, out: StepOutput) -> None:
        self.goal = None
        self.goal_cell = None
        self._planned = False
        self._reject(Rejection(code, reason), now, out)

    def _take_pose(self, pose: Pose, now: float, out: StepOutput) -> None:
        self.pose, self.pose_cell = None, None
        age = now - pose.stamp
        if age > self.config.stale_pose_s:
            return self._reject(Rejection("stale_pose", f"pose is {age:.2f} s old"), now, out)
        self.pose = pose
        if self.map is None:
            return
        cell = xy_to_cell(self.map.shape, pose.x, pose.y, self.config.cell_m)
        if not in_bounds(self.map.shape, cell):
            self.pose = None
            return self._reject(
                Rejection("pose_off_map", f"pose ({pose.x:.2f}, {pose.y:.2f}) m is off the map"),
                now,
                out,
            )
        self.pose_cell = cell

    # -- planning and guidance ------------------------------------------------------------

    def _guide(self, now: float, out: StepOutput) -> None:
        assert self.map is not None and self.goal_cell is not None and self.pose_cell is not None
        assert self.pose is not None
        age = now - self.pose.stamp
        if age > self.config.stale_pose_s:
            # No fresh position: never keep guiding on an old one.
            self.pose, self.pose_cell = None, None
            return self._reject(Rejection("stale_pose", f"no pose for {age:.2f} s"), now, out)
        if not self._planned:
            blocked = self.map.blocked
            self.planner.plan(blocked, self.goal_cell)
            self._planned = True
            self._pending = None  # in the plan
        path, cost = self._path_from(self.pose_cell)
        self._last_path_flat = path[:, 0].astype(np.int64) * self.map.shape[1] + path[:, 1]
        if len(path) == 0:
            self._distance_m = None
            if self.state != NavState.NO_PATH:
                self._reject(Rejection("no_path", "no path to the goal", counted=False), now, out)
            return
        self._distance_m = cost / 10 * self.config.cell_m
        g = self.guidance.guide(path, self.pose, self.map.shape, now, blocked=self.map.blocked)
        out.belt.append(g.pattern)
        if g.cue is not None:
            out.voice.append(g.cue)
        out.path_cells = path
        out.path_meta = dict(
            cost=cost,
            cell_m=self.config.cell_m,
            height=self.map.shape[0],
            width=self.map.shape[1],
            pose_stamp=self.pose.stamp,
            stamp=now,
            map_seq=self.map_seq,
        )
        if g.pattern.kind == PatternKind.ARRIVED:
            self._set_state(NavState.ARRIVED, "", "at the goal", now, out)
            self.goal = None  # done: stay quiet until the next goal
            self.goal_cell = None
            self._planned = False
        elif g.pattern.kind == PatternKind.REROUTE:
            self._set_state(NavState.REROUTING, "", "new path around an obstacle", now, out)
        else:
            self._set_state(NavState.GUIDING, "", "", now, out)

    def _path_from(self, cell: tuple[int, int]) -> tuple[np.ndarray, int]:
        """The planner's path and its cost. From inside the inflation margin (a newly seen
        obstacle grew over where the user stands, or the user drifted off the path) the
        path first leads straight out to the nearby free cell that is cheapest overall."""
        assert self.map is not None
        if not self.map.blocked[cell]:
            path = self._path(cell)
            return path, (int(self.planner.cost_at(cell)) if len(path) else int(INF))
        self._flush_pending()
        return escape_path(
            self.planner, self.map.blocked, self.map.occupancy, cell, self.radius_cells + 2
        )

    # -- reporting ------------------------------------------------------------------------

    def _reject(self, rej: Rejection, now: float, out: StepOutput) -> None:
        outcome = OUTCOMES[rej.code]
        if rej.counted:
            self.rejected += 1
        log.log(
            logging.WARNING if rej.counted else logging.INFO,
            "rejected" if rej.counted else rej.code,
            extra={"fields": {"user": self.user, "code": rej.code, "reason": rej.reason}},
        )
        g = self.guidance.event(outcome.pattern, now, reason=rej.code)
        out.belt.append(g.pattern)
        if g.cue is not None:
            out.voice.append(g.cue)
        self._set_state(outcome.state, rej.code, rej.reason, now, out, force=True)

    def _set_state(
        self,
        state: NavState,
        code: str,
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

    def status(self, now: float, code: str = "", reason: str = "") -> NavStatus:
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
            backend=self.planner.name,
        )
