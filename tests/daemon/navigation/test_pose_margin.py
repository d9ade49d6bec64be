"""ω/2 + a from the pose's uncertainty, WAIT past the limit, and old senders unchanged."""

from __future__ import annotations

import json
import time

import numpy as np
import pytest

from daemon.navigation import Inbox, Navigator, NavigatorSettings
from daemon.planning.dijkstra import dijkstra_field
from protocol import codec
from protocol.messages import Goal, GoalCell, MapDelta, NavState, PatternKind, Pose, StatusCode
from protocol.pose_quality import pose_sigma_m, quality_from_sigma, sigma_from_quality

SHAPE = (40, 40)
BOX = [r * 40 + c for r in range(18, 22) for c in range(10, 30)]  # a box across the middle


def navigator() -> Navigator:
    return Navigator("u", NavigatorSettings(backend="cpu"))  # 10 cm cells, ω/2 = 0.3 m


def delta(seq: int, cells: list[int]) -> MapDelta:
    arr = np.array(cells, dtype=np.int64)
    return MapDelta.from_arrays(seq, SHAPE, arr, np.ones(arr.size, np.uint8), time.time())


def pose(cell, sigma=None, quality=1.0, stamp=None) -> Pose:
    r, c = cell
    return Pose(x=(c + 0.5) / 10, y=(SHAPE[0] - r - 0.5) / 10, heading=1.57,
                stamp=stamp or time.time(), quality=quality, sigma_m=sigma)  # fmt: skip


def goal(r: int, c: int) -> Goal:
    return Goal(target=GoalCell(row=r, col=c), stamp=time.time())


def blocked_count(nav: Navigator) -> int:
    return int(nav.maps.map.blocked.sum())


def test_quality_and_sigma_are_one_figure() -> None:
    for sigma in (0.0, 0.05, 0.25, 1.3):
        assert sigma_from_quality(quality_from_sigma(sigma)) == pytest.approx(sigma)
    assert pose_sigma_m(1.0, None) == 0.0  # an old sender's default: exact
    assert pose_sigma_m(0.5, 0.4) == 0.4  # the sender's own metres win
    assert sigma_from_quality(0.0) == float("inf")


def test_an_old_senders_pose_changes_nothing() -> None:
    raw = json.dumps({"x": 2.05, "y": 0.55, "heading": 1.57, "stamp": time.time()}).encode()
    old = codec.decode(Pose, raw)
    assert old.sigma_m is None and old.quality == 1.0
    nav = navigator()
    nav.step(Inbox(deltas=[delta(0, BOX)], goal=goal(3, 20), pose=old), time.time())
    assert nav.state == NavState.GUIDING and nav.margin.extra_cells == 0
    assert nav.maps.map.radius_cells == nav.radius_cells


@pytest.mark.parametrize("bad", [-0.1, 100.5, float("nan")])
def test_a_bad_sigma_is_refused_whole(bad) -> None:
    raw = json.dumps({"x": 1, "y": 1, "heading": 0, "stamp": 1, "sigma_m": bad}).encode()
    with pytest.raises(codec.DecodeError):
        codec.decode(Pose, raw)


def test_an_unsure_pose_enlarges_the_obstacles_and_the_path_stays_exact() -> None:
    nav = navigator()
    now = time.time()
    nav.step(Inbox(deltas=[delta(0, BOX)], goal=goal(3, 20), pose=pose((36, 20), stamp=now)), now)
    base = blocked_count(nav)
    out = nav.step(Inbox(pose=pose((36, 20), sigma=0.12, stamp=now + 0.1)), now + 0.1)
    # a = 2σ = 0.24 m → 3 cells more around the box.
    assert nav.margin.extra_cells == 3 and nav.margin.a_m == pytest.approx(0.3)
    assert nav.maps.map.radius_cells == nav.radius_cells + 3
    assert blocked_count(nav) > base
    assert out.belt[-1].kind == PatternKind.GUIDE
    assert np.array_equal(nav.route.planner.costs(), dijkstra_field(nav.maps.map.blocked, (3, 20)))
    # A sure pose again: the margin shrinks back, but only after shrink_after_s.
    nav.step(Inbox(pose=pose((36, 20), sigma=0.0, stamp=now + 0.2)), now + 0.2)
    assert nav.margin.extra_cells == 3
    nav.step(Inbox(pose=pose((36, 20), sigma=0.0, stamp=now + 2.5)), now + 2.5)
    assert nav.margin.extra_cells == 0 and blocked_count(nav) == base


def test_a_pose_past_the_limit_gives_wait_not_a_direction() -> None:
    nav = navigator()
    now = time.time()
    nav.step(Inbox(deltas=[delta(0, BOX)], goal=goal(3, 20), pose=pose((36, 20), stamp=now)), now)
    unsure = pose((36, 20), quality=quality_from_sigma(1.5), stamp=now + 0.1)
    out = nav.step(Inbox(pose=unsure), now + 0.1)
    assert out.belt[-1].kind == PatternKind.WAIT
    assert out.statuses[-1].code == StatusCode.POSE_UNCERTAIN
    assert nav.rejected == 0  # not a refused message
    out = nav.step(Inbox(pose=pose((36, 20), sigma=0.05, stamp=now + 0.2)), now + 0.2)
    assert out.belt[-1].kind == PatternKind.GUIDE


def test_the_margin_never_swallows_the_goal_and_gives_way_when_it_closes_the_path() -> None:
    nav = navigator()
    now = time.time()
    # The goal sits 5 cells from the box's south face: ω/2 (3 cells) leaves it free.
    nav.step(Inbox(deltas=[delta(0, BOX)], goal=goal(26, 20), pose=pose((36, 20), stamp=now)), now)
    nav.step(Inbox(pose=pose((36, 20), sigma=0.2, stamp=now + 0.1)), now + 0.1)
    assert not nav.maps.map.blocked[26, 20]
    assert nav.margin.extra_cells == 1  # held one cell short of the goal
    # A wall with a 9-cell gap, beyond the way-out search of the user: ω/2 leaves 3 cells
    # free, ω/2 + 3 cells closes it.
    wall = [20 * 40 + c for c in range(40) if not 15 <= c <= 23]
    nav2 = navigator()
    nav2.step(Inbox(deltas=[delta(0, wall)], goal=goal(3, 20), pose=pose((38, 20), stamp=now)), now)
    nav2.step(Inbox(pose=pose((38, 20), sigma=0.2, stamp=now + 0.1)), now + 0.1)
    assert nav2.state == NavState.NO_PATH
    for k in range(4):
        t = now + 0.2 + 0.1 * k
        nav2.step(Inbox(pose=pose((38, 20), sigma=0.2, stamp=t)), t)
    assert nav2.state == NavState.GUIDING and nav2.margin.extra_cells < 3


def test_arrived_is_said_closer_to_the_goal_the_less_sure_the_pose() -> None:
    """The goal 0.25 m ahead: within the 0.3 m arrival on an exact pose, not on one with
    σ 0.1 m (arrival within 0.2 m then), which is guided on until it is that close."""
    now = time.time()
    gx, gy = 2.05, (SHAPE[0] - 5 - 0.5) / 10  # the centre of cell (5, 20)

    def at(dy: float, sigma: float | None, t: float) -> Pose:
        return Pose(x=gx, y=gy - dy, heading=1.57, stamp=t, sigma_m=sigma)

    exact = navigator()
    exact.step(Inbox(deltas=[delta(0, [0])], goal=goal(5, 20), pose=at(0.25, None, now)), now)
    assert exact.state == NavState.ARRIVED
    unsure = navigator()
    unsure.step(Inbox(deltas=[delta(0, [0])], goal=goal(5, 20), pose=at(0.25, 0.1, now)), now)
    assert unsure.state == NavState.GUIDING
    assert unsure.guidance.arrive_m == pytest.approx(0.2)
    unsure.step(Inbox(pose=at(0.15, 0.1, now + 0.5)), now + 0.5)
    assert unsure.state == NavState.ARRIVED
