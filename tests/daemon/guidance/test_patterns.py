"""Belt patterns: the blend, each event's shape, TTL, pulse rate and hysteresis."""

from __future__ import annotations

import math

import pytest
from hypothesis import given
from hypothesis import strategies as st

from daemon.guidance.patterns import (
    EVENT_SHAPES,
    GUIDE_INTENSITY,
    DirectionHysteresis,
    PatternMaker,
    blend,
    decode,
    pulse_period_ms,
)
from protocol.messages import BeltPattern, PatternKind
from sim.belt_walker import felt_direction


def deg(d: float) -> float:
    return math.radians(d)


@pytest.mark.parametrize(
    ("cw_deg", "motors"),
    [
        (0, (200, 0, 0, 0)),
        (90, (0, 200, 0, 0)),
        (180, (0, 0, 200, 0)),
        (270, (0, 0, 0, 200)),
        (45, (100, 100, 0, 0)),
        (300, (67, 0, 0, 133)),  # 10 o'clock: mostly left, some front
        (-60, (67, 0, 0, 133)),
    ],
)
def test_blend_uses_the_two_nearest_motors(cw_deg: float, motors: tuple) -> None:
    assert blend(deg(cw_deg)) == motors


@given(st.floats(min_value=0.0, max_value=359.9))
def test_decode_inverts_blend(cw_deg: float) -> None:
    motors = blend(deg(cw_deg))
    assert sum(motors) == GUIDE_INTENSITY
    assert sum(m > 0 for m in motors) <= 2
    got = math.degrees(decode(motors))
    err = (got - cw_deg + 180) % 360 - 180
    assert abs(err) < 0.5  # intensity rounding only
    # the simulated walker reads the belt with the same rule
    assert abs((math.degrees(felt_direction(motors)) - cw_deg + 180) % 360 - 180) < 0.5


def test_decode_of_an_idle_belt_is_none() -> None:
    assert decode((0, 0, 0, 0)) is None
    assert felt_direction((0, 0, 0, 0)) is None


def test_pulse_rate_rises_as_obstacles_come_closer() -> None:
    assert pulse_period_ms(None) == 0
    assert pulse_period_ms(2.0) == 0
    assert pulse_period_ms(1.0) == 0
    periods = [pulse_period_ms(d) for d in (0.95, 0.7, 0.5, 0.3, 0.2, 0.0)]
    assert periods == sorted(periods, reverse=True)
    assert periods[0] <= 800 and periods[-1] == 200


def test_each_event_has_its_own_documented_shape() -> None:
    maker = PatternMaker()
    shapes = set()
    for kind in (PatternKind.STOP, PatternKind.ARRIVED, PatternKind.REROUTE,
                 PatternKind.NO_PATH, PatternKind.WAIT):  # fmt: skip
        p = maker.event(kind, 10.0)
        assert isinstance(p, BeltPattern) and p.kind is kind
        assert any(p.motors)
        shapes.add((p.motors, p.period_ms))
    assert len(shapes) == 5
    off = maker.event(PatternKind.OFF, 10.0)
    assert off.motors == (0, 0, 0, 0)
    assert maker.event(PatternKind.STOP, 1.0).motors == (255, 255, 255, 255)
    with pytest.raises(ValueError):
        maker.event(PatternKind.GUIDE, 1.0)


def test_look_drives_a_set_of_motors_no_other_pattern_does() -> None:
    """Turn and look: front and both sides, slowly; RESUMED (the other three-motor pattern)
    is the back and both sides, a steady tap."""
    look = PatternMaker().event(PatternKind.LOOK, 1.0)
    on = {i for i, m in enumerate(look.motors) if m}
    assert on == {0, 1, 3} and look.period_ms == 1000
    for kind, shape in EVENT_SHAPES.items():
        if kind is not PatternKind.LOOK:
            assert {i for i, m in enumerate(shape.motors) if m} != on, kind


def test_no_event_feels_like_guide() -> None:
    """GUIDE drives at most two adjacent motors and never pulses slower than 800 ms. It
    never drives the back motor alone (a target behind is TURN_AROUND: see the next test),
    so PAUSED, the back motor alone, cannot be taken for a direction."""
    for kind, shape in EVENT_SHAPES.items():
        if kind is PatternKind.OFF:
            continue
        on = [i for i, m in enumerate(shape.motors) if m]
        adjacent_pair = len(on) == 2 and (on[1] - on[0]) % 4 in (1, 3)
        single = len(on) == 1 and on != [2]
        assert not (single or adjacent_pair) or shape.period_ms > 800, kind


def test_guide_never_drives_the_back_motor_alone() -> None:
    """Guidance turns a target more than 135° off into TURN_AROUND; within ±135° neither the
    blend nor the hysteresis's snap to an axis leaves the back motor running alone."""
    hyst = DirectionHysteresis()
    for step in range(-1350, 1351, 5):  # sweep both ways: the snap depends on the past
        for cw in (deg(step / 10), deg(-step / 10)):
            motors = blend(hyst(cw))
            assert [i for i, m in enumerate(motors) if m] != [2], step


def test_turn_around_points_back_and_to_the_side_to_turn() -> None:
    maker = PatternMaker()
    right = maker.turn_around(deg(160), 0.0)  # target behind, a little to the right
    left = maker.turn_around(deg(200), 0.0)
    assert right.kind is PatternKind.TURN_AROUND and right.motors == (0, 255, 255, 0)
    assert left.motors == (0, 0, 255, 255)
    assert right.period_ms > 0


def test_every_pattern_carries_a_ttl_and_a_sequence() -> None:
    maker = PatternMaker()
    made = [maker.guide(deg(30), None, 1.0), maker.turn_around(deg(180), 1.0)]
    made += [maker.event(k, 1.0) for k in EVENT_SHAPES]
    for p in made:
        assert 50 <= p.ttl_ms <= 5000
    seqs = [p.seq for p in made]
    assert seqs == sorted(seqs) and len(set(seqs)) == len(seqs)
    # a guide pattern expires quickly: the belt goes quiet soon after the daemon stops
    assert made[0].ttl_ms <= 1000


def test_hysteresis_keeps_one_motor_while_walking_straight() -> None:
    h = DirectionHysteresis()
    felt = [blend(h(deg(a))) for a in (3, -5, 8, -10, 11, -4, 15, -17)]
    assert all(m == (200, 0, 0, 0) for m in felt)
    # without the filter the second motor would flip sides at every sign change
    raw = [blend(deg(a)) for a in (3, -5, 8, -10)]
    assert {m[1] > 0 for m in raw} == {True, False}


def test_hysteresis_enters_and_leaves_the_snap_at_different_angles() -> None:
    h = DirectionHysteresis(snap_enter_deg=12, snap_leave_deg=20, dead_band_deg=0)
    assert h(deg(25)) == pytest.approx(deg(25))  # outside: a blend
    assert h(deg(18)) == pytest.approx(deg(18))  # not yet inside the enter zone
    assert h(deg(10)) == 0.0  # snapped
    assert h(deg(18)) == 0.0  # still snapped: leave is 20°
    assert h(deg(22)) == pytest.approx(deg(22))  # left


def test_hysteresis_dead_band_ignores_small_changes() -> None:
    h = DirectionHysteresis()
    first = h(deg(45))
    assert h(deg(48)) == first
    assert h(deg(42)) == first
    assert h(deg(60)) == pytest.approx(deg(60))


def test_hysteresis_rejects_a_leave_angle_below_enter() -> None:
    with pytest.raises(ValueError):
        DirectionHysteresis(snap_enter_deg=20, snap_leave_deg=10)
