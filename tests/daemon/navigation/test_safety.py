"""Safety decisions hold: a STOP or WAIT is not undone by the same step, a map known to be out
of date is never guided on, and input far off the scale is refused, not a crash."""

from __future__ import annotations

import time

import numpy as np

from daemon.navigation import Inbox, Navigator, NavigatorSettings, Rejection
from protocol.messages import (
    Goal,
    GoalCell,
    GoalMetres,
    MapDelta,
    MapSnapshot,
    NavState,
    PatternKind,
    Pose,
    StatusCode,
)

SHAPE = (30, 30)


def pose(cell: tuple[int, int], stamp: float | None = None, far: float | None = None) -> Pose:
    r, c = cell
    x, y = (c + 0.5) / 10, (SHAPE[0] - r - 0.5) / 10
    return Pose(x=far or x, y=far or y, heading=1.57, stamp=time.time() if stamp is None else stamp)


def guiding() -> Navigator:
    s = Navigator("u", NavigatorSettings(backend="cpu"))
    now = time.time()
    first = MapDelta.from_arrays(0, SHAPE, np.array([0]), np.array([1]), now)
    out = s.step(Inbox(deltas=[first], goal=Goal(target=GoalCell(row=3, col=15), stamp=now),
                       pose=pose((26, 15))), now)  # fmt: skip
    assert s.state == NavState.GUIDING and kinds(out) == [PatternKind.GUIDE]
    return s


def kinds(out) -> list[PatternKind]:
    return [b.kind for b in out.belt]


def test_a_map_known_to_be_stale_is_waited_on_not_guided_on_until_the_snapshot():
    s = guiding()
    gap = MapDelta.from_arrays(5, SHAPE, np.array([400]), np.array([1]), time.time())
    out = s.step(Inbox(deltas=[gap], pose=pose((26, 15))), time.time())
    assert kinds(out) == [PatternKind.WAIT] and out.want_snapshot and out.path_cells is None
    for r in (25, 24):  # new poses, no snapshot yet: still WAIT, never a GUIDE
        out = s.step(Inbox(pose=pose((r, 15))), time.time())
        assert kinds(out) == [PatternKind.WAIT] and out.path_cells is None
    out = s.step(Inbox(snapshot_failed=True, pose=pose((24, 15))), time.time())
    assert kinds(out) == [PatternKind.WAIT]  # no snapshot came: the map is still stale
    occ = np.full(SHAPE, 2, np.uint8)
    occ.reshape(-1)[[0, 400]] = 1
    snap = MapSnapshot.from_array(5, occ, time.time())
    out = s.step(Inbox(snapshot=snap, pose=pose((24, 15))), time.time())
    assert kinds(out) == [PatternKind.GUIDE] and s.maps.map.occupancy.reshape(-1)[400] == 1


def test_a_refusal_stops_the_user_and_the_same_step_does_not_guide_again():
    s = guiding()
    bad = Rejection(StatusCode.MALFORMED, "not a message")
    out = s.step(Inbox(rejections=[bad], pose=pose((25, 15))), time.time())
    assert kinds(out) == [PatternKind.STOP] and out.path_cells is None
    assert [st.code for st in out.statuses] == [StatusCode.MALFORMED]
    out = s.step(Inbox(pose=pose((25, 15))), time.time())
    assert kinds(out) == [PatternKind.GUIDE]  # the next step, with a good pose, guides again


def test_a_pose_stamped_in_the_future_is_refused():
    s = guiding()
    out = s.step(Inbox(pose=pose((25, 15), stamp=time.time() + 5.0)), time.time())
    assert kinds(out) == [PatternKind.STOP] and s.state == NavState.STALE
    assert "ahead" in out.statuses[-1].reason


def test_a_goal_or_a_pose_at_the_wires_limit_is_off_the_map_not_a_crash():
    # 1e308 m is refused at the edge (tests/protocol/test_bounds.py); the largest the wire
    # takes reaches the navigator and is simply off the map.
    s = guiding()
    out = s.step(Inbox(pose=pose((25, 15), far=1e6)), time.time())
    assert [st.code for st in out.statuses] == [StatusCode.POSE_OFF_MAP]
    far_goal = Goal(target=GoalMetres(x=-1e6, y=1e6), stamp=time.time())
    out = s.step(Inbox(goal=far_goal, pose=pose((25, 15))), time.time())
    assert out.statuses[-1].code == StatusCode.GOAL_OFF_MAP and s.goal is None


def test_staleness_is_judged_on_the_daemons_receive_clock_not_on_a_slow_step():
    s = guiding()
    t = time.time()
    s.step(Inbox(pose=pose((25, 15), stamp=t), pose_received=t, taken_at=t), t)
    # The daemon got round to the next step 3 s late, but took its inputs 0.5 s after the
    # pose arrived: the localiser was not silent, so no stale_pose.
    out = s.step(Inbox(tick=True, taken_at=t + 0.5), t + 3.0)
    assert kinds(out) == [PatternKind.GUIDE] and s.state == NavState.GUIDING
    # Nothing received for 1.5 s when the inputs were taken: stale, whatever the step's clock.
    out = s.step(Inbox(tick=True, taken_at=t + 1.5), t + 1.5)
    assert kinds(out) == [PatternKind.STOP] and out.statuses[-1].code == StatusCode.STALE_POSE


def test_a_pose_already_old_when_it_arrived_is_refused_and_a_fresh_one_guides():
    s = guiding()
    t = time.time()
    out = s.step(Inbox(pose=pose((25, 15), stamp=t - 2.0), pose_received=t, taken_at=t), t)
    assert kinds(out) == [PatternKind.STOP] and "old when it arrived" in out.statuses[-1].reason
    out = s.step(Inbox(pose=pose((25, 15), stamp=t + 0.2), pose_received=t + 0.25), t + 0.3)
    assert kinds(out) == [PatternKind.GUIDE]


def test_a_shed_user_waits_and_hears_overloaded_and_keeps_map_goal_and_pose():
    s = guiding()
    wall = MapDelta.from_arrays(1, SHAPE, np.array([20 * 30 + 15]), np.array([1]), time.time())
    out = s.step(Inbox(deltas=[wall], pose=pose((25, 15)), overloaded=True), time.time())
    assert kinds(out) == [PatternKind.WAIT] and out.path_cells is None
    assert out.statuses[-1].code == StatusCode.OVERLOADED
    assert s.maps.map.occupancy.reshape(-1)[20 * 30 + 15] == 1 and s.goal_cell == (3, 15)
    out = s.step(Inbox(pose=pose((25, 15))), time.time())  # guided again: from where it was
    assert kinds(out) == [PatternKind.GUIDE] and out.path_cells is not None
    assert (20, 15) not in map(tuple, out.path_cells.tolist())


def test_a_pose_the_daemon_has_not_read_makes_a_missing_pose_overload_not_stale():
    s = guiding()
    t = time.time()
    s.step(Inbox(pose=pose((25, 15), stamp=t), pose_received=t, taken_at=t), t)
    # 2 s without a pose read, but a newer one reached the daemon (queued on its loop, or
    # dropped while the user was shed): the daemon's doing, said as such, and no guidance.
    out = s.step(Inbox(tick=True, taken_at=t + 2.0, pose_unread=True), t + 2.0)
    assert kinds(out) == [PatternKind.WAIT] and out.path_cells is None
    assert [st.code for st in out.statuses] == [StatusCode.OVERLOADED]
    assert StatusCode.STALE_POSE not in s.rejected_by_code
    # Readmitted and a fresh pose read: guided again.
    out = s.step(Inbox(pose=pose((25, 15), stamp=t + 2.1), pose_received=t + 2.1), t + 2.1)
    assert kinds(out) == [PatternKind.GUIDE]


def test_a_pose_that_never_comes_back_is_said_stale_once_the_daemon_has_caught_up():
    s = guiding()
    t = time.time()
    s.step(Inbox(pose=pose((25, 15), stamp=t), pose_received=t, taken_at=t), t)
    out = s.step(Inbox(tick=True, taken_at=t + 2.0, pose_unread=True), t + 2.0)
    assert [st.code for st in out.statuses] == [StatusCode.OVERLOADED]
    # The daemon caught up and no pose came: the localiser is silent, and says so.
    out = s.step(Inbox(tick=True, taken_at=t + 2.5), t + 2.5)
    assert kinds(out) == [PatternKind.STOP] and out.path_cells is None
    assert [st.code for st in out.statuses] == [StatusCode.STALE_POSE]
    # Still none: said once, and nothing guides.
    out = s.step(Inbox(tick=True, taken_at=t + 3.0), t + 3.0)
    assert not out.belt and not out.statuses and not out.voice and out.path_cells is None
    out = s.step(Inbox(pose=pose((25, 15), stamp=t + 3.1), pose_received=t + 3.1), t + 3.1)
    assert kinds(out) == [PatternKind.GUIDE]
