"""After a STOP before contact, guidance turns the user away from what the camera saw, even
when the planner's map (and a wrong pose) says the way ahead is clear."""

from __future__ import annotations

import math
import time

import numpy as np

from daemon.guidance.patterns import decode, pulse_period_ms
from daemon.navigation import Inbox, Navigator, NavigatorSettings
from daemon.navigation.blocked_side import BlockedSideSettings
from protocol.messages import Goal, GoalCell, MapDelta, PatternKind, Pose, Proximity

SHAPE = (30, 30)
NORTH, EAST = math.pi / 2, 0.0


def pose(now: float, heading: float = NORTH) -> Pose:
    """An estimated pose (with its sigma, as the RFID filter sends): the turn away is for a
    pose that may be off; an exact pose's map holds what the camera saw."""
    return Pose(x=1.55, y=0.45, heading=heading, stamp=now, sigma_m=0.05)


def seen(now: float, ahead: float | None, bearing: float = 0.0) -> Proximity:
    return Proximity(ahead_m=ahead, nearest_m=ahead, bearing=bearing, frame_stamp=now, stamp=now)


def guiding(now: float) -> Navigator:
    """A clear map, the goal due north: the planner says straight on."""
    s = Navigator("u", NavigatorSettings(backend="cpu"))
    first = MapDelta.from_arrays(0, SHAPE, np.array([0]), np.array([1]), now)
    goal = Goal(target=GoalCell(row=3, col=15), stamp=now)
    out = s.step(Inbox(deltas=[first], goal=goal, pose=pose(now)), now)
    assert [b.kind for b in out.belt] == [PatternKind.GUIDE]
    assert abs(_off_front(out.belt[-1])) < 0.2
    return s


def _off_front(pattern) -> float:
    """The GUIDE's direction, radians counter-clockwise from the front (as bearings)."""
    cw = decode(pattern.motors)
    assert cw is not None
    return -math.remainder(cw, 2 * math.pi)


def _stopped(s: Navigator, now: float, ahead: float, bearing: float = 0.0) -> float:
    out = s.step(Inbox(pose=pose(now), proximity=seen(now, ahead, bearing)), now)
    assert [b.kind for b in out.belt] == [PatternKind.STOP]
    return now + 0.8  # past the STOP's hold


def test_after_a_stop_a_guide_into_the_obstacle_turns_away_from_its_side() -> None:
    now = time.time()
    s = guiding(now)
    # The camera sees an obstacle 0.15 m ahead, a little to the left; the map has none.
    t = _stopped(s, now, 0.15, bearing=0.3)
    out = s.step(Inbox(pose=pose(t), proximity=seen(t, 0.15, bearing=0.3)), t)
    assert [b.kind for b in out.belt] == [PatternKind.GUIDE]
    away = _off_front(out.belt[-1])
    assert away < -math.radians(60), math.degrees(away)  # to the right, off the blocked side
    assert s.safety.blocked.turned == 1


def test_turned_away_the_obstacle_out_of_view_is_still_not_walked_back_into() -> None:
    now = time.time()
    s = guiding(now)
    t = _stopped(s, now, 0.15)
    s.step(Inbox(pose=pose(t), proximity=seen(t, 0.15)), t)
    # The user turned right to face east: the camera no longer sees the obstacle, and the
    # planner (goal due north) says turn left, back into it.
    t += 0.6
    out = s.step(Inbox(pose=pose(t, EAST), proximity=seen(t, None)), t)
    assert [b.kind for b in out.belt] == [PatternKind.GUIDE]
    world = EAST + _off_front(out.belt[-1])
    assert abs(math.remainder(world - NORTH, 2 * math.pi)) > math.radians(60)


def test_a_guide_towards_an_obstacle_with_room_left_pulses_for_that_room() -> None:
    now = time.time()
    s = guiding(now)
    t = _stopped(s, now, 0.5)
    out = s.step(Inbox(pose=pose(t), proximity=seen(t, 0.5)), t)
    assert [b.kind for b in out.belt] == [PatternKind.GUIDE]
    assert abs(_off_front(out.belt[-1])) < 0.2  # its direction kept: 0.45 m is free
    period = out.belt[-1].period_ms
    assert 0 < period <= pulse_period_ms(0.5 - BlockedSideSettings().margin_m)


def test_without_a_stop_or_once_it_is_forgotten_guidance_is_untouched() -> None:
    now = time.time()
    s = guiding(now)
    out = s.step(Inbox(pose=pose(now), proximity=seen(now, 0.7)), now)  # beyond stop_m
    assert [b.kind for b in out.belt] == [PatternKind.GUIDE] and out.belt[-1].period_ms == 0
    t = _stopped(s, now, 0.15)
    t += BlockedSideSettings().memory_s + 0.1  # no close reading since
    out = s.step(Inbox(pose=pose(t), proximity=seen(t, None)), t)
    assert abs(_off_front(out.belt[-1])) < 0.2 and out.belt[-1].period_ms == 0
    assert not s.safety.blocked.points
