"""What a user's runner takes and puts per step: poses straight from zenoh's thread (no hop to
the loop, the worker woken only when idle), and a GUIDE pattern not put again each step while
it is unchanged, yet always within its TTL."""

from __future__ import annotations

import asyncio
import time

import numpy as np
import pytest

from daemon.navigation import Navigator
from daemon.service.bridge import Bridge
from daemon.service.config import DaemonConfig
from daemon.service.embedded import free_port, open_peer
from daemon.service.runner import Pacing, UserRunner
from protocol import codec
from protocol import topics as T
from protocol.messages import (
    BeltPattern,
    Goal,
    GoalCell,
    MapDelta,
    NavPath,
    NavStatus,
    PatternKind,
    Pose,
    StatusCode,
)
from protocol.session import loopback, open_session

SHAPE = (40, 40)


def walls() -> MapDelta:
    cells = np.flatnonzero(np.pad(np.zeros((38, 38), bool), 1, constant_values=True))
    return MapDelta.from_arrays(0, SHAPE, cells, np.ones(cells.size), time.time())


def pose(stamp: float | None = None) -> Pose:
    # Row 30, column 20 (0.1 m cells), facing the goal straight ahead (north): GUIDE front.
    return Pose(x=2.05, y=0.95, heading=1.5708, stamp=stamp or time.time())


def goal() -> Goal:
    return Goal(target=GoalCell(row=8, col=20), stamp=time.time())


async def until(check, timeout_s: float = 5.0) -> bool:
    deadline = time.monotonic() + timeout_s
    while not check():
        if time.monotonic() > deadline:
            return False
        await asyncio.sleep(0.01)
    return True


@pytest.mark.timeout(60)
def test_poses_from_zenohs_thread_step_an_idle_user_and_a_bad_one_is_refused():
    port = free_port()
    published: list[tuple[str, bytes]] = []

    def of(leaf: str, kind):
        return [codec.decode(kind, b) for k, b in published if k.endswith("/" + leaf)]

    async def scenario() -> None:
        session = open_session(loopback(listen_port=port))
        peer = open_peer(port)
        bridge = Bridge(session, asyncio.get_running_loop(), lambda *a: None, lambda t, q: q.drop())
        navigator = Navigator("ann", DaemonConfig(backend="cpu").navigator_settings())
        runner = UserRunner(navigator, lambda k, b: published.append((k, b)), lambda *a: None, 1.0)
        try:
            bridge.start()
            bridge.watch("ann")
            bridge.route_poses("ann", runner.take_pose)
            pose_pub = peer.declare_publisher(T.POSE.key("ann"))
            runner.put_delta(walls())
            runner.put_goal(goal())
            # The first step ran (it put what it decided) and the worker waits for any input;
            # the bridge's subscription has reached the peer, or the pose would go nowhere.
            # Waited for, not slept on: either can take longer on a loaded machine.
            assert await until(lambda: bool(published))
            assert await until(lambda: pose_pub.matching_status.matching)
            sent = pose()
            pose_pub.put(codec.encode(sent))
            assert await until(lambda: any(p.pose_stamp == sent.stamp for p in of("path", NavPath)))
            assert bridge.pose_heard_at("ann") is not None
            await asyncio.sleep(0.3)
            peer.put(T.POSE.key("ann"), b"{not json")  # refused at once, on the loop
            assert await until(
                lambda: any(s.code == StatusCode.MALFORMED for s in of("status", NavStatus))
            )
            assert of("belt", BeltPattern)[-1].kind == PatternKind.STOP
            bridge.mute("ann", True)  # shed: its poses stop on zenoh's thread
            steps = navigator.steps
            peer.put(T.POSE.key("ann"), codec.encode(pose()))
            await asyncio.sleep(0.3)
            assert navigator.steps == steps
        finally:
            await runner.close()
            bridge.close()
            peer.close()
            session.close()

    asyncio.run(scenario())


def run_guided(listened: bool, seconds: float = 1.5) -> tuple[list, list, list[float]]:
    """A user standing still, poses at 50 Hz, steps at 25 Hz: (belts, paths, belt times)."""
    published: list[tuple[str, bytes, float]] = []

    async def scenario() -> None:
        navigator = Navigator("u", DaemonConfig(backend="cpu").navigator_settings())
        runner = UserRunner(
            navigator,
            lambda k, b: published.append((k, b, time.monotonic())),
            lambda *a: None,
            1.0,
            pacing=Pacing(slots=1, guide_hz=25.0),
            listened=lambda key: listened,
        )
        runner.put_delta(walls())
        runner.put_goal(goal())
        end = time.monotonic() + seconds
        while time.monotonic() < end:
            runner.put_pose(pose())
            await asyncio.sleep(0.02)
        await runner.close()

    asyncio.run(scenario())
    belts = [(codec.decode(BeltPattern, b), t) for k, b, t in published if k.endswith("/belt")]
    paths = [b for k, b, _ in published if k.endswith("/path")]
    guides = [t for p, t in belts if p.kind == PatternKind.GUIDE]
    return [p for p, _ in belts], paths, guides


@pytest.mark.timeout(60)
def test_an_unchanged_guide_pattern_is_put_again_only_as_its_ttl_needs():
    belts, paths, guides = run_guided(listened=False)
    assert not paths  # nobody listens to the path: not built
    assert {tuple(p.motors) for p in belts if p.kind == PatternKind.GUIDE} == {(200, 0, 0, 0)}
    # ~35 steps in 1.5 s; the pattern is put every half TTL (0.35 s) plus at most a step.
    assert 3 <= len(guides) <= 8
    gaps = np.diff(guides)
    assert gaps.max() < 0.7  # always inside GUIDE's 700 ms TTL: the belt never goes quiet
    assert gaps.min() >= 0.35
    assert belts[-1].kind == PatternKind.STOP  # the last words are always put


@pytest.mark.timeout(60)
def test_every_pattern_is_put_while_someone_pairs_it_with_the_path():
    _belts, paths, guides = run_guided(listened=True)
    assert len(guides) == len(paths) >= 20  # one pattern with every path, as the sim walks on


def readmitted(readmitted_s_ago: float, then_a_pose: bool) -> list[tuple[str, bytes]]:
    """A user guided, shed past its pose's staleness (0.4 s), guided again ``readmitted_s_ago``
    seconds ago with no pose since: what the steps after that publish."""
    published: list[tuple[str, bytes]] = []

    async def scenario() -> None:
        settings = DaemonConfig(backend="cpu", stale_pose_s=0.4).navigator_settings()
        runner = UserRunner(
            Navigator("u", settings), lambda k, b: published.append((k, b)), lambda *a: None, 1.0
        )

        # Each step waited for by what it puts, not for a fixed time: a loaded machine may
        # take longer, and a step that came late would put its words after the clear below.
        def said(leaf: str, model) -> list:
            return [codec.decode(model, b) for k, b in list(published) if k.endswith("/" + leaf)]

        def guided() -> bool:
            return any(b.kind == PatternKind.GUIDE for b in said("belt", BeltPattern))

        runner.put_delta(walls())
        runner.put_goal(goal())
        runner.put_pose(pose())
        assert await until(guided)
        runner.shed = True  # as admission control does; its poses stop coming
        runner.tick()
        shed_at = time.monotonic()
        assert await until(
            lambda: any(s.code == StatusCode.OVERLOADED for s in said("status", NavStatus))
        )
        await asyncio.sleep(0.8 - (time.monotonic() - shed_at))  # the pose is past 0.4 s old
        published.clear()
        runner.readmitted_at, runner.shed = time.time() - readmitted_s_ago, False
        runner.tick()
        assert await until(lambda: bool(said("status", NavStatus)))  # the readmission's step
        if then_a_pose:
            runner.put_pose(pose())
            assert await until(guided)
        await runner.close()

    asyncio.run(scenario())
    return published


@pytest.mark.timeout(60)
def test_a_readmitted_user_without_a_pose_yet_hears_overloaded_never_stale():
    """Shed, a user's poses are not even sent to the daemon: once guided again, a missing pose
    is the daemon's doing until one is read, for at most a pose's staleness."""
    published = readmitted(0.0, then_a_pose=True)
    codes = [codec.decode(NavStatus, b).code for k, b in published if k.endswith("/status")]
    assert codes[0] == StatusCode.OVERLOADED and StatusCode.STALE_POSE not in codes
    assert codes[-1] == StatusCode.SHUTDOWN
    belts = [codec.decode(BeltPattern, b) for k, b in published if k.endswith("/belt")]
    # The first fresh pose guides again; then close()'s STOP.
    assert [b.kind for b in belts][-2:] == [PatternKind.GUIDE, PatternKind.STOP]


@pytest.mark.timeout(60)
def test_a_user_readmitted_longer_ago_than_a_poses_staleness_without_one_is_stale():
    published = readmitted(1.0, then_a_pose=False)
    codes = [codec.decode(NavStatus, b).code for k, b in published if k.endswith("/status")]
    assert codes == [StatusCode.STALE_POSE, StatusCode.SHUTDOWN]  # the localiser went quiet
