"""After a STOP's hold, the GUIDE leads around what the frame shows, not into it."""

from __future__ import annotations

import math
import time

import numpy as np

from daemon.guidance.patterns import PatternMaker, blend, decode
from daemon.navigation import Inbox, Navigator, NavigatorSettings
from daemon.navigation.lead_around import LeadAround, free_run
from daemon.planning.grid import FREE, OCCUPIED
from protocol.messages import Goal, GoalCell, MapDelta, PatternKind, Pose, Proximity

SHAPE = (30, 30)


def pose(r: int, c: int, now: float) -> Pose:
    return Pose(x=(c + 0.5) / 10, y=(SHAPE[0] - r - 0.5) / 10, heading=math.pi / 2, stamp=now)


def person(ahead: float, now: float) -> Proximity:
    """A person standing straight ahead, not on the map."""
    return Proximity(ahead_m=ahead, nearest_m=ahead, bearing=0.0, frame_stamp=now, stamp=now)


def walking_north(now: float, walls: list[int] = ()) -> Navigator:  # type: ignore[assignment]
    """Guided from (25, 15) to (3, 15): the path runs straight on (north, the heading)."""
    s = Navigator("u", NavigatorSettings(backend="cpu"))
    cells = np.array([0, *walls])
    first = MapDelta.from_arrays(0, SHAPE, cells, np.full(cells.size, OCCUPIED), now)
    out = s.step(Inbox(deltas=[first], goal=Goal(target=GoalCell(row=3, col=15), stamp=now),
                       pose=pose(25, 15, now)), now)  # fmt: skip
    assert [b.kind for b in out.belt] == [PatternKind.GUIDE]
    assert abs(decode(out.belt[0].motors)) < 0.05  # straight on
    return s


def stopped_then(s: Navigator, ahead: float, now: float, steps: int = 4) -> list:
    """A STOP for the person, its hold, then ``steps`` steps after it: the belt of each."""
    first = s.step(Inbox(pose=pose(25, 15, now), proximity=person(ahead, now)), now)
    assert [b.kind for b in first.belt] == [PatternKind.STOP]
    belts = []
    for k in range(steps):
        t = now + 0.6 + 0.1 * k
        out = s.step(Inbox(pose=pose(25, 15, t), proximity=person(ahead, t)), t)
        belts.append(out.belt)
    return belts


def test_a_person_not_on_the_map_straight_on_gets_a_turned_guide_never_straight_on():
    now = time.time()
    s = walking_north(now)
    for belt in stopped_then(s, 0.03, now):
        assert [b.kind for b in belt] == [PatternKind.GUIDE]  # no deadlock: the user is led
        cw = decode(belt[0].motors)
        # 3 cm from the person: only a step square to it or away keeps clear of its bound.
        assert abs(math.remainder(cw, 2 * math.pi)) >= math.radians(90), math.degrees(cw)
    assert s.safety.around.led == 4 and s.safety.stops == 1


def test_the_turned_guide_keeps_clear_of_the_map_too():
    now = time.time()
    # A wall 0.25 m to the left (west) of the user: the turn goes right (east), though
    # with the map clear it goes left.
    walls = [r * SHAPE[1] + 12 for r in range(20, 29)]
    s = walking_north(now, walls)
    for belt in stopped_then(s, 0.03, now, steps=2):
        cw = decode(belt[0].motors)
        assert math.remainder(cw, 2 * math.pi) > math.radians(80), math.degrees(cw)  # right


def test_creeping_in_after_the_hold_stops_the_user_again():
    now = time.time()
    s = walking_north(now)
    stopped_then(s, 0.5, now, steps=1)  # the hold ended at 0.5 m
    t = now + 0.8
    out = s.step(Inbox(pose=pose(25, 15, t), proximity=person(0.47, t)), t)
    assert [b.kind for b in out.belt] == [PatternKind.GUIDE]  # within creep_m: not a step
    t += 0.1
    out = s.step(Inbox(pose=pose(25, 15, t), proximity=person(0.4, t)), t)
    assert [b.kind for b in out.belt] == [PatternKind.STOP]  # 0.1 m nearer, under rearm_m
    assert s.safety.stops == 2


def test_turned_away_the_person_out_of_view_is_not_walked_back_into():
    now = time.time()
    s = walking_north(now)
    stopped_then(s, 0.03, now, steps=1)
    # The frame shows nothing now (the user turned away); the planner's map still has no
    # person and says straight on, into them: the kept person turns it away again.
    t = now + 0.8
    clear = Proximity(ahead_m=None, nearest_m=None, bearing=None, frame_stamp=t, stamp=t)
    out = s.step(Inbox(pose=pose(25, 15, t), proximity=clear), t)
    assert [b.kind for b in out.belt] == [PatternKind.GUIDE]
    assert abs(math.remainder(decode(out.belt[0].motors), 2 * math.pi)) >= math.radians(60)
    # Once the memory lapses, guidance is the planner's again.
    t += 6.5
    out = s.step(Inbox(pose=pose(25, 15, t), proximity=clear.model_copy(update={"stamp": t,
                 "frame_stamp": t})), t)  # fmt: skip
    assert abs(math.remainder(decode(out.belt[0].motors), 2 * math.pi)) < 0.05


def test_a_guide_that_already_keeps_clear_is_left_and_none_clear_stops():
    now = time.time()
    free = np.full(SHAPE, FREE, np.uint8)
    maker = PatternMaker()
    here = pose(15, 15, now)
    seen = person(0.05, now)
    side = maker.guide(math.radians(-110), None, now)  # 110° to the left of the person
    assert free_run(-decode(side.motors), seen) == math.inf
    assert LeadAround(0.6).steer(side, seen, here, free, 0.1, maker, now) is None
    ahead = maker.guide(0.0, None, now)
    boxed = np.full(SHAPE, OCCUPIED, np.uint8)
    boxed[13:16, 14:17] = FREE  # walled in on the map, the person not on it: no step clear
    out = LeadAround(0.6).steer(ahead, seen, here, boxed, 0.1, maker, now)
    assert out is not None and out.kind == PatternKind.STOP
    turned = LeadAround(0.6).steer(ahead, seen, here, free, 0.1, maker, now)
    assert turned is not None and turned.kind == PatternKind.GUIDE
    assert turned.motors != blend(0.0)
    mapped = free.copy()
    mapped[14, 15] = OCCUPIED  # the map holds it: the planner's GUIDE is its business
    assert LeadAround(0.6).steer(ahead, seen, here, mapped, 0.1, maker, now) is None


def test_a_turned_guide_keeps_off_what_the_frame_shows_on_the_map_too():
    now = time.time()
    free = np.full(SHAPE, FREE, np.uint8)
    maker = PatternMaker()
    here = pose(15, 15, now)
    lead = LeadAround(0.6)
    ahead = maker.guide(0.0, None, now)
    first = lead.steer(ahead, person(0.05, now), here, free, 0.1, maker, now)
    assert first is not None and 0 < decode(first.motors) < math.pi  # to the right
    # The frame now shows a box the map holds, 0.35 m away on the right; the kept person
    # still turns the straight-on GUIDE, and the turn goes left, off both.
    mapped = free.copy()
    mapped[15, 19:21] = OCCUPIED  # beyond the map check's 0.3 m step: the frame bounds it
    box = Proximity(ahead_m=None, nearest_m=0.35, bearing=-math.pi / 2, frame_stamp=now, stamp=now)
    out = lead.steer(ahead, box, here, mapped, 0.1, maker, now + 0.1, held=False)
    assert out is not None and out.kind == PatternKind.GUIDE
    assert decode(out.motors) > math.pi, math.degrees(decode(out.motors))  # left
