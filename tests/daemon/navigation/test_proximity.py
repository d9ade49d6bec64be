"""STOP before contact: the mapper's proximity overrides guidance in the same step."""

from __future__ import annotations

import time

import numpy as np

from daemon.navigation import Inbox, Navigator, NavigatorSettings
from protocol.messages import Goal, GoalCell, MapDelta, NavState, PatternKind, Pose, Proximity

SHAPE = (30, 30)


def pose(r: int, c: int, now: float) -> Pose:
    return Pose(x=(c + 0.5) / 10, y=(SHAPE[0] - r - 0.5) / 10, heading=1.57, stamp=now)


def near(ahead: float | None, now: float, nearest: float | None = None,
         bearing: float | None = None) -> Proximity:  # fmt: skip
    nearest = ahead if nearest is None else nearest
    return Proximity(ahead_m=ahead, nearest_m=nearest, bearing=0.0 if bearing is None else bearing,
                     frame_stamp=now, stamp=now)  # fmt: skip


def guiding(now: float, stop_m: float = 0.6) -> Navigator:
    s = Navigator("u", NavigatorSettings(backend="cpu", stop_m=stop_m))
    first = MapDelta.from_arrays(0, SHAPE, np.array([0]), np.array([1]), now)
    out = s.step(Inbox(deltas=[first], goal=Goal(target=GoalCell(row=3, col=15), stamp=now),
                       pose=pose(26, 15, now)), now)  # fmt: skip
    assert [b.kind for b in out.belt] == [PatternKind.GUIDE]
    return s


def test_obstacle_closer_than_stop_m_stops_whatever_the_planner_says():
    now = time.time()
    s = guiding(now)
    # The planner's map is clear ahead; the camera's latest frame is not.
    out = s.step(Inbox(pose=pose(25, 15, now + 0.1), proximity=near(0.4, now + 0.1)), now + 0.1)
    kinds = [b.kind for b in out.belt]
    assert kinds == [PatternKind.STOP], kinds  # no GUIDE after it in the same step
    assert out.path_cells is None
    assert any(c.kind == "stop" for c in out.voice)
    assert s.safety.stops == 1


def test_stop_is_held_then_guidance_leads_around_and_a_closer_obstacle_stops_again():
    now = time.time()
    s = guiding(now)
    s.step(Inbox(proximity=near(0.5, now)), now)
    held = s.step(Inbox(pose=pose(25, 15, now + 0.2)), now + 0.2)  # same obstacle, in the hold
    assert [b.kind for b in held.belt] == [PatternKind.STOP]
    after = s.step(Inbox(pose=pose(25, 15, now + 0.8), proximity=near(0.5, now + 0.8)), now + 0.8)
    assert [b.kind for b in after.belt] == [PatternKind.GUIDE]  # stopped and felt: go on
    closer = s.step(Inbox(proximity=near(0.3, now + 0.9), pose=pose(25, 15, now + 0.9)), now + 0.9)
    assert [b.kind for b in closer.belt] == [PatternKind.STOP] and s.safety.stops == 2


def test_configurable_distance_and_clear_way():
    now = time.time()
    s = guiding(now, stop_m=0.3)
    out = s.step(Inbox(pose=pose(25, 15, now), proximity=near(0.4, now)), now)
    assert [b.kind for b in out.belt] == [PatternKind.GUIDE]  # 0.4 m is beyond 0.3 m
    out = s.step(Inbox(pose=pose(25, 15, now), proximity=near(None, now)), now)
    assert [b.kind for b in out.belt] == [PatternKind.GUIDE]


def test_an_old_proximity_is_not_acted_on():
    now = time.time()
    s = guiding(now)
    out = s.step(Inbox(pose=pose(25, 15, now), proximity=near(0.2, now - 5.0)), now)
    assert [b.kind for b in out.belt] == [PatternKind.GUIDE]


def test_not_guiding_the_obstacle_is_felt_on_its_side():
    now = time.time()
    s = Navigator("u", NavigatorSettings(backend="cpu"))
    # Nearest 0.8 m away, 90° to the left (bearing +π/2): the left motor alone, fast pulse.
    out = s.step(Inbox(proximity=near(None, now, nearest=0.8, bearing=1.5708)), now)
    assert [b.kind for b in out.belt] == [PatternKind.OBSTACLE]
    motors = out.belt[0].motors
    assert motors[3] > 0 and motors[0] == motors[1] == motors[2] == 0
    assert out.belt[0].period_ms < 200  # faster than any GUIDE pulse
    assert s.state == NavState.IDLE


def looking(seen: bool | None, now: float) -> Proximity:
    return Proximity(target_seen=seen, frame_stamp=now, stamp=now)


def test_no_goal_and_the_target_not_in_view_says_turn_and_look():
    now = time.time()
    s = Navigator("u", NavigatorSettings(backend="cpu"))
    out = s.step(Inbox(proximity=looking(False, now)), now)
    assert [b.kind for b in out.belt] == [PatternKind.LOOK]
    assert out.belt[0].motors == (180, 180, 0, 180) and out.belt[0].period_ms == 1000
    assert [c.text for c in out.voice] == ["turn slowly and look for the target"]
    # Every frame keeps the belt on; the voice does not nag (a routine cue, 12 s apart).
    again = s.step(Inbox(proximity=looking(False, now + 0.2)), now + 0.2)
    assert [b.kind for b in again.belt] == [PatternKind.LOOK] and again.voice == []
    later = s.step(Inbox(proximity=looking(False, now + 13.0)), now + 13.0)
    assert [c.text for c in later.voice] == ["turn slowly and look for the target"]


def test_no_look_when_the_target_is_seen_a_camera_does_not_look_or_guidance_is_on():
    now = time.time()
    idle = Navigator("u", NavigatorSettings(backend="cpu"))
    for seen in (True, None):
        out = idle.step(Inbox(proximity=looking(seen, now)), now)
        assert out.belt == [] and out.voice == []
    s = guiding(now)  # guiding to where the target was seen: it may leave the view
    out = s.step(Inbox(pose=pose(25, 15, now + 0.1), proximity=looking(False, now + 0.1)),
                 now + 0.1)  # fmt: skip
    assert [b.kind for b in out.belt] == [PatternKind.GUIDE]


def test_a_pose_that_overtook_its_frame_waits_for_it_and_the_frame_decides():
    # The daemon takes a pose straight into the inbox while the frame's proximity waits for
    # the loop: the step of pose 2 may come before frame 2, which was taken before pose 2.
    now = time.time()
    s = guiding(now)  # pose 0 at now, no camera yet
    out = s.step(Inbox(proximity=near(None, now + 0.05), pose=pose(25, 15, now + 0.06)), now + 0.06)
    assert [b.kind for b in out.belt] == [PatternKind.GUIDE]  # frame 1 after pose 0
    ahead = s.step(Inbox(pose=pose(24, 15, now + 0.16)), now + 0.16)  # frame 2 not read yet
    assert ahead.belt == [] and ahead.path_cells is None  # no GUIDE from frame 1's view
    assert s.safety.overtaken == 1
    stop = s.step(Inbox(proximity=near(0.3, now + 0.15)), now + 0.17)  # frame 2 sees it
    assert [b.kind for b in stop.belt] == [PatternKind.STOP]
    # The same with a clear frame: it guides, from pose 2.
    s = guiding(now)
    s.step(Inbox(proximity=near(None, now + 0.05), pose=pose(25, 15, now + 0.06)), now + 0.06)
    assert s.step(Inbox(pose=pose(24, 15, now + 0.16)), now + 0.16).belt == []
    go = s.step(Inbox(proximity=near(None, now + 0.15)), now + 0.17)
    assert [b.kind for b in go.belt] == [PatternKind.GUIDE]
    assert go.path_meta["pose_stamp"] == now + 0.16


def test_a_frame_stamped_as_its_pose_covers_that_pose_not_the_next():
    now = time.time()
    s = guiding(now)
    out = s.step(Inbox(proximity=near(None, now + 0.1), pose=pose(25, 15, now + 0.1)), now + 0.1)
    assert [b.kind for b in out.belt] == [PatternKind.GUIDE]
    again = s.step(Inbox(pose=pose(25, 15, now + 0.1)), now + 0.12)  # the same pose again
    assert [b.kind for b in again.belt] == [PatternKind.GUIDE]
    assert s.step(Inbox(pose=pose(24, 15, now + 0.2)), now + 0.2).belt == []
    # A camera that stopped (frames older than max_age_s) is not waited for, as before.
    late = s.step(Inbox(pose=pose(24, 15, now + 1.5)), now + 1.5)
    assert [b.kind for b in late.belt] == [PatternKind.GUIDE]
