"""The simulated world as its own zenoh node: the same ``World`` as the in-process walks.

For one user it plays everything outside the daemon through ``sim.world.World``: the mapper
(sensor deltas on ``MAP_DELTA``, snapshots of what it has published on ``MAP_SOURCE``), the
localiser (``POSE``) and the person (a walker moving on the true map). It runs in lock step
with the daemon: publish a pose, wait for the path planned from that very pose, let the
walker act on it (and on the belt pattern published with it), sense, publish the delta,
wait for the path planned on it, repeat. A pose is re-sent every ``pose_period_s`` while
nothing comes back, so the daemon never sees it go stale while it is merely waiting for a
goal.

Each time the daemon's liveliness token appears (``ALIVE``: the first time, and again after a
daemon restart) the node resends what the daemon may have missed while it was down: its last
delta (a daemon that lost the map then sees a gap and asks for the snapshot) and, given a
``goal``, the goal, as the user's client would. A restarted map source (``restart_mapper``)
starts a new epoch at sequence 0.

Walkers are those of ``sim.world.WALKERS`` (``--follow``).
"""

from __future__ import annotations

import math
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np
import zenoh
from zenoh.handlers import Callback

from daemon.planning.grid import Cell
from protocol import codec
from protocol import session as wire
from protocol import topics as T
from protocol.messages import (
    BeltPattern,
    Goal,
    MapDelta,
    NavPath,
    NavState,
    NavStatus,
    PatternKind,
)

from .courtyard import Scenario
from .world import WALKERS, Walker, World

__all__ = ["WALKERS", "SimNode", "SimResult"]


@dataclass
class SimResult:
    arrived: bool
    reason: str
    walked: list[tuple[int, int]] = field(default_factory=list)
    """The user's cell after every step, start first."""
    step_ms: list[float] = field(default_factory=list)
    """Pose sent → path for that pose received: the daemon's whole loop, as the user sees it."""
    belts: list[BeltPattern] = field(default_factory=list)
    """The pattern the belt showed when the walker acted, one per path acted on."""
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
        start: Cell | None = None,
        heading: float = math.pi / 2,
        fov_deg: float = 80.0,
        pose_period_s: float = 0.2,
        step_period_s: float = 0.0,
        seed: int = 0,
        goal: Goal | None = None,
    ) -> None:
        self.session = session
        self.goal = goal
        self._daemon_came = threading.Event()
        """The daemon's token appeared: (re)send from the walk's thread what it may lack."""
        self.goals_sent = 0
        self._last_delta: bytes | None = None
        self.user = T.check_user(user)
        self.scenario = scenario
        self.shape = scenario.shape
        self.cell_m = scenario.cell_m
        self.world = World(
            scenario, walker, seed=seed, start=start, heading=heading, fov_deg=fov_deg
        )
        self.pose_period_s = pose_period_s
        self.step_period_s = step_period_s
        self._cond = threading.Condition()
        self._path: NavPath | None = None
        self._belt: BeltPattern | None = None
        self._status: NavStatus | None = None
        self._map_lock = threading.Lock()
        """The world's known map and sequence change on the walk's thread; the map source
        queryable reads them on zenoh's."""
        self._entities: list = []

    @property
    def walker(self) -> Walker:
        return self.world.walker

    @walker.setter
    def walker(self, walker: Walker) -> None:
        self.world.walker = walker

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
        self._entities.append(
            wire.watch_liveliness(s, T.ALIVE, Callback(self._on_alive, indirect=False))
        )
        if self.goal is not None:
            self._pub_goal = wire.declare_publisher(s, T.GOAL, u)
            self._entities.append(self._pub_goal)

    def _on_alive(self, sample: zenoh.Sample) -> None:
        if sample.kind == zenoh.SampleKind.PUT:
            self._daemon_came.set()  # acted on by the walk, not on zenoh's thread

    def _resend_if_daemon_came(self) -> None:
        """The daemon appeared (at first, or back after a restart): the client sends its
        goal, and the mapper its last delta again. A daemon that has it ignores it; one that
        lost the map sees a gap and asks for the snapshot."""
        if not self._daemon_came.is_set():
            return
        self._daemon_came.clear()
        if self.goal is not None:
            self._pub_goal.put(codec.encode(self.goal))
            self.goals_sent += 1
        with self._map_lock:
            last = self._last_delta
        if last is not None:
            self._pub_delta.put(last)

    def _put_delta(self, delta: MapDelta) -> None:
        data = codec.encode(delta)
        with self._map_lock:
            self._last_delta = data
        self._pub_delta.put(data)

    def _on_path(self, sample: zenoh.Sample) -> None:
        path = codec.decode(NavPath, sample.payload.to_bytes())
        with self._cond:
            self._path = path
            self._cond.notify_all()

    def _on_belt(self, sample: zenoh.Sample) -> None:
        belt = codec.decode(BeltPattern, sample.payload.to_bytes())
        with self._cond:
            self._belt = belt
            self._cond.notify_all()

    def _on_status(self, sample: zenoh.Sample) -> None:
        status = codec.decode(NavStatus, sample.payload.to_bytes())
        with self._cond:
            self._status = status
            self._cond.notify_all()

    def _on_source(self, query: zenoh.Query) -> None:
        with self._map_lock:
            snap = self.world.snapshot(time.time())
        wire.reply(query, T.MAP_SOURCE, self.user, codec.encode(snap))
        query.drop()

    def close(self) -> None:
        for ent in self._entities:
            ent.undeclare()
        self._entities = []

    # -- the world ------------------------------------------------------------------------

    def cell(self) -> Cell:
        return self.world.cell()

    def _sense(self, stop: threading.Event) -> None:
        """Publish what the sensor sees now, then wait (at most a pose period) for the path
        the daemon planned on it: the next pose then meets a map that already holds it, so
        the daemon's steps come in the same order whatever its timing."""
        with self._map_lock:
            deltas = self.world.sense(time.time())
        if not deltas:
            return
        for delta in deltas:
            self._put_delta(delta)
        seq = deltas[-1].seq
        self._await(lambda: self._path is not None and self._path.map_seq >= seq, stop)

    def _send_pose(self) -> float:
        stamp = time.time()
        self._pub_pose.put(codec.encode(self.world.pose(stamp)))
        return stamp

    def restart_mapper(self, epoch: int | None = None) -> None:
        """The map source restarts: a new epoch, delta 0 again (``World.restart_mapper``)."""
        with self._map_lock:
            deltas = self.world.restart_mapper(time.time(), epoch)
        for delta in deltas:
            self._put_delta(delta)

    def _start_map(self) -> None:
        """Delta 0 carries the known obstacles when they fit in one; else the daemon, seeing
        delta 1 first, asks ``MAP_SOURCE`` for a snapshot."""
        with self._map_lock:
            deltas = self.world.first_deltas(time.time())
        for delta in deltas:
            self._put_delta(delta)

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
            self._start_map()  # the first sensing included
            deadline = time.monotonic() + timeout_s
            while not stop.is_set():
                if time.monotonic() > deadline:
                    result.reason = "timeout"
                    break
                self._resend_if_daemon_came()
                t0 = time.perf_counter()
                stamp = self._send_pose()
                path = self._wait_for_path(stamp, stop)
                belt = self._wait_for_belt(path.stamp, stop) if path is not None else None
                at_goal = belt is not None and belt.kind == PatternKind.ARRIVED
                if at_goal:
                    self._await(self._arrived, stop)  # that step's status comes after its belt
                if at_goal or self._arrived():
                    result.arrived, result.reason = True, "arrived"
                    break
                if path is None:
                    continue
                result.step_ms.append((time.perf_counter() - t0) * 1e3)
                cells = np.array(path.cells, dtype=np.int32).reshape(-1, 2)
                if belt is not None:
                    result.belts.append(belt)
                action = self.world.act(cells, belt, time.time())
                result.actions[action] = result.actions.get(action, 0) + 1
                if action == "step":
                    result.walked.append(self.cell())
                if action == "bump":
                    self._bumped(path, belt)
                if action in ("step", "turn", "bump"):  # a bump turned the user, too
                    self._sense(stop)
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
                result.known = self.world.known.copy()
            self.close()
        return result

    def _bumped(self, path: NavPath, belt: BeltPattern | None) -> None:
        """A step ran into something; a node that knows more of its world records what."""

    def _wait_for_belt(self, stamp: float, stop: threading.Event) -> BeltPattern | None:
        """The pattern made in the same step as the path stamped ``stamp`` (the daemon sends
        it first, but on another key), so the walker feels what that step decided; None (the
        walker stands) if it did not come: another step's pattern was decided on other data."""

        def same() -> BeltPattern | None:
            b = self._belt
            return b if b is not None and abs(b.stamp - stamp) < 1e-6 else None

        self._await(lambda: same() is not None, stop)
        with self._cond:
            return same()

    def _wait_for_path(self, stamp: float, stop: threading.Event) -> NavPath | None:
        """The path planned from the pose sent at ``stamp``; None on ARRIVED or timeout."""
        self._await(lambda: self._planned_from(stamp) or self._arrived(stamp), stop)
        return self._path if self._planned_from(stamp) else None

    def _planned_from(self, stamp: float) -> bool:
        return self._path is not None and abs(self._path.pose_stamp - stamp) < 1e-6

    def _arrived(self, since: float = 0.0) -> bool:
        s = self._status
        return s is not None and s.state == NavState.ARRIVED and s.stamp >= since

    def _await(self, done: Callable[[], bool], stop: threading.Event) -> bool:
        """Wait at most a pose period for ``done()`` (read under the lock the callbacks take)."""
        end = time.monotonic() + self.pose_period_s
        with self._cond:
            while not done():
                left = end - time.monotonic()
                if stop.is_set() or left <= 0:
                    return False
                self._cond.wait(left)
        return True
