"""The simulated world as its own zenoh node: true map, sensor, and a user who walks.

For one user it plays everything outside the daemon: the mapper (sensor deltas on
``map/delta``, snapshots of what it has seen on ``map/source``), the localiser (``pose``)
and the person (a ``Walker`` moving on the true map). It runs in lock step with the
daemon: publish a pose, wait for the path planned from that very pose, let the walker act
on it (and on the belt pattern published with it), sense, publish the delta, repeat. A
pose is re-sent every ``pose_period_s`` while nothing comes back, so the daemon never
sees it go stale while it is merely waiting for a goal.

Walkers are pluggable: ``WALKERS`` maps a name (``--follow``) to a factory. ``path`` steps
to the next cell of the planned path; a belt-reading walker reacts to the pattern only.
"""

from __future__ import annotations

import math
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Protocol

import numpy as np
import zenoh
from zenoh.handlers import Callback

from daemon.planning.grid import OCCUPIED, cell_to_xy, xy_to_cell
from protocol import codec
from protocol import session as wire
from protocol import topics as T
from protocol.messages import (
    MAX_DELTA_CELLS,
    BeltPattern,
    MapDelta,
    MapSnapshot,
    NavPath,
    NavState,
    NavStatus,
    Pose,
)

from .belt_walker import belt_walker_for, step_hits
from .courtyard import Scenario
from .sensor import Sensor
from .walk import LOOKAHEAD_M, heading_along


@dataclass
class WalkerView:
    """What a walker may use to act once."""

    path: np.ndarray | None
    """``(k, 2)`` cells planned from the user's current cell, or None."""
    belt: BeltPattern | None
    """The pattern the belt is showing now."""
    true: np.ndarray
    """The world's occupancy, to find out the hard way what a step runs into."""


class Walker(Protocol):
    x: float
    y: float
    heading: float

    def act(self, view: WalkerView) -> str:
        """Act once: ``"step"``, ``"turn"``, ``"stand"`` or ``"bump"`` (a collision)."""
        ...


@dataclass
class PathWalker:
    """Steps to the centre of the next cell of the path, facing half a metre ahead on it."""

    x: float
    y: float
    heading: float
    cell_m: float
    collisions: int = 0

    def act(self, view: WalkerView) -> str:
        path = view.path
        if path is None or len(path) < 2:
            return "stand"
        shape = view.true.shape
        x1, y1 = cell_to_xy(shape, (int(path[1][0]), int(path[1][1])), self.cell_m)
        lookahead = max(1, round(LOOKAHEAD_M / self.cell_m))
        if step_hits(view.true, self.cell_m, self.x, self.y, x1, y1):
            self.collisions += 1
            return "bump"
        self.x, self.y = x1, y1
        self.heading = heading_along(path[1:], lookahead, self.heading)
        return "step"


def _path_walker(scenario: Scenario, x: float, y: float, heading: float) -> Walker:
    return PathWalker(x, y, heading, scenario.cell_m)


WALKERS: dict[str, Callable[[Scenario, float, float, float], Walker]] = {
    "path": _path_walker,
    "belt": belt_walker_for,
}
"""``--follow`` name → factory ``(scenario, x, y, heading) -> Walker``."""


@dataclass
class SimResult:
    arrived: bool
    reason: str
    walked: list[tuple[int, int]] = field(default_factory=list)
    """The user's cell after every step, start first."""
    step_ms: list[float] = field(default_factory=list)
    """Pose sent → path for that pose received: the daemon's whole loop, as the user sees it."""
    actions: dict[str, int] = field(default_factory=dict)
    last_status: NavStatus | None = None
    known: np.ndarray | None = None
    """What the sensor had seen by the end."""

    @property
    def steps(self) -> int:
        return max(0, len(self.walked) - 1)


class SimNode:
    """One simulated user in one world, on its own zenoh session."""

    def __init__(
        self,
        session: zenoh.Session,
        user: str,
        scenario: Scenario,
        walker: str = "path",
        start: tuple[int, int] | None = None,
        heading: float = math.pi / 2,
        fov_deg: float = 80.0,
        pose_period_s: float = 0.2,
        step_period_s: float = 0.0,
    ) -> None:
        self.session = session
        self.user = T.check_user(user)
        self.scenario = scenario
        self.shape = scenario.shape
        self.cell_m = scenario.cell_m
        self.sensor = Sensor(scenario.sensor_range_cells, fov_deg)
        self.known = scenario.known.copy()
        self.seq = -1
        self.pose_period_s = pose_period_s
        self.step_period_s = step_period_s
        x, y = cell_to_xy(self.shape, start or scenario.start, self.cell_m)
        self.walker = WALKERS[walker](scenario, x, y, heading)
        self._cond = threading.Condition()
        self._path: NavPath | None = None
        self._belt: BeltPattern | None = None
        self._status: NavStatus | None = None
        self._map_lock = threading.Lock()
        self._entities: list = []

    # -- zenoh ----------------------------------------------------------------------------

    def _declare(self) -> None:
        s, u = self.session, self.user
        self._pub_delta = wire.declare_publisher(s, T.MAP_DELTA, u)
        self._pub_pose = wire.declare_publisher(s, T.POSE, u)
        self._entities = [
            self._pub_delta,
            self._pub_pose,
            wire.declare_subscriber(s, T.PATH, Callback(self._on_path, indirect=False), u),
            wire.declare_subscriber(s, T.BELT, Callback(self._on_belt, indirect=False), u),
            wire.declare_subscriber(s, T.STATUS, Callback(self._on_status, indirect=False), u),
            wire.declare_queryable(s, T.MAP_SOURCE, Callback(self._on_source, indirect=False), u),
        ]

    def _on_path(self, sample: zenoh.Sample) -> None:
        path = codec.decode(NavPath, sample.payload.to_bytes())
        with self._cond:
            self._path = path
            self._cond.notify_all()

    def _on_belt(self, sample: zenoh.Sample) -> None:
        self._belt = codec.decode(BeltPattern, sample.payload.to_bytes())

    def _on_status(self, sample: zenoh.Sample) -> None:
        status = codec.decode(NavStatus, sample.payload.to_bytes())
        with self._cond:
            self._status = status
            self._cond.notify_all()

    def _on_source(self, query: zenoh.Query) -> None:
        with self._map_lock:
            snap = MapSnapshot.from_array(max(self.seq, 0), self.known, time.time())
        wire.reply(query, T.MAP_SOURCE, self.user, codec.encode(snap))
        query.drop()

    def close(self) -> None:
        for ent in self._entities:
            ent.undeclare()
        self._entities = []

    # -- the world ------------------------------------------------------------------------

    def cell(self) -> tuple[int, int]:
        return xy_to_cell(self.shape, self.walker.x, self.walker.y, self.cell_m)

    def _send_delta(self, cells: np.ndarray, values: np.ndarray) -> None:
        with self._map_lock:
            self.known.reshape(-1)[cells] = values
            self.seq += 1
            seq = self.seq
        delta = MapDelta.from_arrays(seq, self.shape, cells, values, time.time())
        self._pub_delta.put(codec.encode(delta))

    def _sense(self) -> None:
        cells, values = self.sensor.sense(
            self.scenario.true, self.known, self.cell(), self.walker.heading
        )
        if cells.size:
            self._send_delta(cells, values)

    def _send_pose(self) -> float:
        stamp = time.time()
        pose = Pose(x=self.walker.x, y=self.walker.y, heading=self.walker.heading, stamp=stamp)
        self._pub_pose.put(codec.encode(pose))
        return stamp

    def _start_map(self) -> None:
        """Delta 0 carries the known obstacles when they fit in one; else the daemon, seeing
        delta 1 first, asks ``map/source`` for a snapshot."""
        occupied = np.flatnonzero(self.known == OCCUPIED)
        if occupied.size <= MAX_DELTA_CELLS:
            self._send_delta(occupied, np.full(occupied.size, OCCUPIED, np.uint8))
        else:
            self.seq = 0

    # -- the walk -------------------------------------------------------------------------

    def run(
        self,
        stop: threading.Event | None = None,
        max_steps: int | None = None,
        timeout_s: float = 120.0,
        on_step: Callable[[SimResult], None] | None = None,
    ) -> SimResult:
        """Walk until the daemon says ARRIVED, ``stop`` is set, or a limit is reached."""
        stop = stop or threading.Event()
        max_steps = max_steps if max_steps is not None else 10 * sum(self.shape)
        result = SimResult(arrived=False, reason="stopped", walked=[self.cell()])
        self._declare()
        try:
            time.sleep(0.05)  # let the daemon's subscribers match ours before delta 0
            self._start_map()
            self._sense()
            deadline = time.monotonic() + timeout_s
            while not stop.is_set():
                if time.monotonic() > deadline:
                    result.reason = "timeout"
                    break
                t0 = time.perf_counter()
                stamp = self._send_pose()
                path = self._wait_for_path(stamp, stop)
                status = self._status
                if status is not None and status.state == NavState.ARRIVED:
                    result.arrived, result.reason = True, "arrived"
                    break
                if path is None:
                    continue
                result.step_ms.append((time.perf_counter() - t0) * 1e3)
                cells = np.array(path.cells, dtype=np.int32).reshape(-1, 2)
                action = self.walker.act(WalkerView(cells, self._belt, self.scenario.true))
                result.actions[action] = result.actions.get(action, 0) + 1
                if action == "step":
                    result.walked.append(self.cell())
                if action in ("step", "turn", "bump"):  # a bump turned the user, too
                    self._sense()
                if on_step is not None:
                    on_step(result)
                if result.steps >= max_steps:
                    result.reason = "step limit"
                    break
                if self.step_period_s:
                    stop.wait(self.step_period_s)
        finally:
            result.last_status = self._status
            with self._map_lock:
                result.known = self.known.copy()
            self.close()
        return result

    def _wait_for_path(self, stamp: float, stop: threading.Event) -> NavPath | None:
        """The path planned from the pose sent at ``stamp``; None on ARRIVED or timeout."""
        end = time.monotonic() + self.pose_period_s
        with self._cond:
            while not stop.is_set():
                p, s = self._path, self._status
                if p is not None and abs(p.pose_stamp - stamp) < 1e-6:
                    return p
                if s is not None and s.state == NavState.ARRIVED and s.stamp >= stamp:
                    return None
                left = end - time.monotonic()
                if left <= 0:
                    return None
                self._cond.wait(left)
        return None
