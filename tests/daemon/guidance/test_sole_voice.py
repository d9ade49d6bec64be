"""The voice that guides alone (``sole_voice.py``): when it speaks, and "stop" before contact."""

from __future__ import annotations

import math

import numpy as np
import pytest

from daemon.guidance.cues import CueMaker
from daemon.guidance.guide import Guidance
from daemon.guidance.sole_voice import SoleVoice, SoleVoiceSettings, crosses_occupied, sole_limiter
from daemon.planning.grid import FREE, OCCUPIED
from protocol.messages import PatternKind, Pose

NORTH = math.pi / 2  # headings: 0 east, counter-clockwise


def sole() -> SoleVoice:
    return SoleVoice(CueMaker("en", sole_limiter()))


def open_map(n: int = 40) -> np.ndarray:
    return np.full((n, n), FREE, dtype=np.uint8)


def test_a_segment_that_crosses_an_occupied_cell_or_leaves_the_map_is_caught() -> None:
    occ = open_map(10)
    occ[3, 5] = OCCUPIED
    user = np.array([8.5, 5.5])  # row, col in cells; north is a smaller row
    assert crosses_occupied(occ, user, np.array([2.5, 5.5]))
    assert not crosses_occupied(occ, user, np.array([4.5, 5.5]))
    assert not crosses_occupied(occ, user, np.array([2.5, 8.5]))
    assert crosses_occupied(occ, user, np.array([8.5, 11.0]))  # off the map


def test_stop_before_contact_only_for_a_user_who_walks_or_turns() -> None:
    occ = open_map()
    occ[20, 15:26] = OCCUPIED  # a wall across the way north
    v = sole()
    user = np.array([26.5, 20.5])
    # First sight of the user: nothing to compare with, so standing.
    assert v.stop_before_contact(occ, None, user, NORTH, 0.1, 0.0) == (False, None)
    user = np.array([25.5, 20.5])  # a step north: walking, 0.45 m from the wall
    danger, cue = v.stop_before_contact(occ, None, user, NORTH, 0.1, 0.6)
    assert danger and cue is not None and cue.text == "stop" and v.stops == 1
    # Standing still in front of the wall: not "stop" again, the way is owed instead.
    assert v.stop_before_contact(occ, None, user, NORTH, 0.1, 1.2) == (False, None)
    # Turned on the spot towards the wall (from east): about to walk into it.
    v.stop_before_contact(occ, None, user, 0.0, 0.1, 1.8)
    danger, cue = v.stop_before_contact(occ, None, user, NORTH, 0.1, 2.4)
    assert danger and cue is not None
    # Walking east along the wall, clear of it: no stop.
    v.stop_before_contact(occ, None, np.array([25.5, 10.5]), 0.0, 0.1, 3.0)
    assert v.stop_before_contact(occ, None, np.array([25.5, 11.5]), 0.0, 0.1, 3.6)[0] is False


def test_a_step_from_free_space_into_the_margin_is_stopped() -> None:
    occ = open_map()
    blocked = np.zeros(occ.shape, dtype=bool)
    blocked[15:22, :] = True  # a margin band north of the user, no obstacle on the line
    v = sole()
    v.stop_before_contact(occ, blocked, np.array([26.5, 20.5]), NORTH, 0.1, 0.0)
    danger, _ = v.stop_before_contact(occ, blocked, np.array([25.5, 20.5]), NORTH, 0.1, 0.6)
    assert danger  # the next 0.5 m step ends at row 20.5, inside the margin


def test_the_way_is_said_at_the_start_after_a_stop_off_course_and_to_reassure() -> None:
    v = sole()
    target, user = np.array([10.5, 20.5]), np.array([30.5, 20.5])
    first = v.way(target, user, 0.0, 2.0, 0.1, 0.0)
    assert first is not None and first.text == "straight ahead, 2 metres"
    # On course, said just now:
    assert v.way(target, user + np.array([-3, 0]), 0.0, 1.7, 0.1, 1.0) is None
    # Off course by 40°: corrected at once, once the gap since the last cue has passed.
    assert v.way(target, user + np.array([-5, 0]), math.radians(-40), 1.5, 0.1, 1.2) is None  # gap
    fix = v.way(target, user + np.array([-5, 0]), math.radians(-40), 1.5, 0.1, 1.6)
    assert fix is not None and fix.text == "turn to 1 o'clock, then 2 metres"
    # On course and moving: quiet until the reassurance interval.
    assert v.way(target, user + np.array([-8, 0]), 0.0, 1.2, 0.1, 5.0) is None
    again = v.way(target, user + np.array([-12, 0]), 0.0, 0.8, 0.1, 7.7)
    assert again is not None and again.text == "straight ahead, 1 metre"
    # After a safety cue the way is owed: said as soon as the gap allows, same words or not.
    v.after_safety()
    assert v.way(target, user + np.array([-12, 0]), 0.0, 0.8, 0.1, 9.3) is not None


def test_a_user_who_stands_still_hears_the_way_again() -> None:
    v = sole()
    target, user = np.array([10.5, 20.5]), np.array([30.5, 20.5])
    assert v.way(target, user, math.radians(90), 2.0, 0.1, 0.0) is not None
    assert v.way(target, user, 0.0, 2.0, 0.1, 1.6) is None
    stalled = v.way(target, user, 0.0, 2.0, 0.1, SoleVoiceSettings().stall_s + 0.1)
    assert stalled is not None and stalled.text == "straight ahead, 2 metres"


def test_near_an_obstacle_a_turn_is_said_on_the_spot_first() -> None:
    occ = open_map()
    occ[21:26, 22:28] = OCCUPIED  # right beside the user, to the east and north-east
    v = sole()
    user = np.array([25.5, 20.5])
    # The target is at 2 o'clock (60° right of north): a person turning by ear could land
    # anywhere within ±60° of it, into the block. Turn, stand, and wait for the way.
    cue = v.way(np.array([20.5, 24.5]), user, math.radians(-60), 1.0, 0.1, 0.0, occ, NORTH)
    assert cue is not None and cue.text == "turn to 2 o'clock and wait"
    # Far from anything the same turn is said with its distance.
    v2 = sole()
    cue = v2.way(np.array([20.5, 24.5]), user, math.radians(-60), 1.0, 0.1, 0.0, open_map(),
                 NORTH)  # fmt: skip
    assert cue is not None and cue.text == "turn to 2 o'clock, then 1 metre"


def test_cues_never_pile_up_and_stop_is_not_repeated_within_a_second() -> None:
    limiter = sole_limiter()
    cues = CueMaker("en", limiter)
    said = [t for t in np.arange(0.0, 6.0, 0.1) if cues.direction(0.3, 2.0, float(t))]
    assert np.all(np.diff(said) >= SoleVoiceSettings().min_gap_s - 1e-9)
    assert cues.event(PatternKind.STOP, 10.0) is not None
    assert cues.event(PatternKind.STOP, 10.5) is None
    assert cues.event(PatternKind.STOP, 11.1) is not None


def test_guidance_in_sole_mode_stops_a_walker_heading_for_a_wall() -> None:
    occ = open_map()
    occ[20, 5:35] = OCCUPIED
    blocked = occ == OCCUPIED
    g = Guidance(cell_m=0.1, voice="sole")
    path = np.array([(26, c) for c in range(20, 36)], dtype=np.int32)  # the way is east
    shape = occ.shape
    # Poses in metres: x east, y north; the user walks north towards the wall at row 20.
    out = g.guide(path, Pose(x=2.05, y=1.35, heading=NORTH, stamp=0.0), shape, 0.0, blocked, occ)
    assert out.cue is not None and out.cue.kind == "direction"
    out = g.guide(path, Pose(x=2.05, y=1.55, heading=NORTH, stamp=0.6), shape, 0.6, blocked, occ)
    assert out.pattern.kind == PatternKind.STOP and out.cue is not None and out.cue.text == "stop"
    with pytest.raises(ValueError, match="companion or sole"):
        Guidance(voice="loud")  # type: ignore[arg-type]
