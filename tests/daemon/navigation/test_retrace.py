"""An unsure pose leads the user back along their own steps to where it was last sure, and the
route resumes once the pose is good again; with no sure place on the track, WAIT as before."""

from __future__ import annotations

import time

import numpy as np

from daemon.navigation import Inbox, Navigator, NavigatorSettings
from daemon.navigation.retrace import BACK_REASON, Retrace
from protocol.messages import (
    Goal,
    GoalCell,
    MapDelta,
    NavState,
    PatternKind,
    Pose,
    StatusCode,
)

SHAPE = (40, 40)


def pose(cell, sigma, stamp=None, heading=1.57) -> Pose:
    r, c = cell
    return Pose(x=(c + 0.5) / 10, y=(SHAPE[0] - r - 0.5) / 10, heading=heading,
                stamp=stamp or time.time(), sigma_m=sigma)  # fmt: skip


def test_the_way_back_runs_along_the_track_to_the_last_sure_place() -> None:
    track = Retrace()
    for r, sigma in [(36, 0.1), (33, 0.2), (30, 0.5), (27, 0.7), (24, 0.9)]:
        track.record(pose((r, 20), sigma))
    assert track.way_back(pose((22, 20), 0.9), False, SHAPE, 0.1, (22, 20)) is None
    back = track.way_back(pose((22, 20), 1.2), True, SHAPE, 0.1, (22, 20))
    assert back is not None and track.active
    assert tuple(back[0]) == (22, 20) and tuple(back[-1]) == (33, 20)  # the last sure crumb
    assert all(abs(int(a) - int(b)) <= 1 for a, b in zip(back[:-1, 0], back[1:, 0], strict=True))
    # Below the WAIT limit but not yet sure: still led back (no flipping at the limit).
    back = track.way_back(pose((28, 20), 0.8), False, SHAPE, 0.1, (28, 20))
    assert back is not None and tuple(back[-1]) == (33, 20)
    assert all(row > 27 for row in back[:, 0])  # crumbs passed are dropped
    assert track.way_back(pose((31, 20), 0.5), False, SHAPE, 0.1, (31, 20)) is None
    assert not track.active


def test_no_sure_place_on_the_track_gives_nothing_to_follow() -> None:
    track = Retrace()
    for r in (36, 33, 30):
        track.record(pose((r, 20), 0.8))
    assert track.way_back(pose((28, 20), 1.3), True, SHAPE, 0.1, (28, 20)) is None
    track = Retrace()
    track.record(pose((36, 20), 0.1))
    # At the sure place and still unsure: it is passed, nothing older is left.
    assert track.way_back(pose((36, 20), 1.3), True, SHAPE, 0.1, (36, 20)) is None


def test_the_navigator_leads_back_then_resumes_the_route() -> None:
    nav = Navigator("u", NavigatorSettings(backend="cpu"))
    now = time.time()
    goal = Goal(target=GoalCell(row=3, col=20), stamp=now)
    box = np.array([r * 40 + c for r in range(18, 22) for c in range(30, 38)], np.int64)
    room = MapDelta.from_arrays(0, SHAPE, box, np.ones(box.size, np.uint8), now)
    nav.step(Inbox(deltas=[room], goal=goal, pose=pose((36, 20), 0.1, now)), now)
    for i, r in enumerate((34, 32, 30, 28), start=1):
        out = nav.step(Inbox(pose=pose((r, 20), 0.1 + 0.1 * i, now + i)), now + i)
        assert out.belt[-1].kind == PatternKind.GUIDE
    # σ past the limit: no WAIT, the belt turns the user back south, towards row 36.
    out = nav.step(Inbox(pose=pose((27, 20), 1.3, now + 5)), now + 5)
    assert out.belt[-1].kind == PatternKind.TURN_AROUND
    assert out.statuses[-1].code == StatusCode.POSE_UNCERTAIN
    assert out.statuses[-1].reason == BACK_REASON and nav.state == NavState.STALE
    out = nav.step(Inbox(pose=pose((30, 20), 0.9, now + 6, heading=-1.57)), now + 6)
    assert out.belt[-1].kind == PatternKind.GUIDE and nav.retrace.active
    # A fix: the route to the goal again.
    out = nav.step(Inbox(pose=pose((31, 20), 0.15, now + 7, heading=-1.57)), now + 7)
    assert not nav.retrace.active and nav.state == NavState.GUIDING
    assert out.belt[-1].kind in (PatternKind.GUIDE, PatternKind.TURN_AROUND)
