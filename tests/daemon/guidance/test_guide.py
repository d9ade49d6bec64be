"""Guidance: path + pose → belt pattern + cue, end to end through its pieces."""

from __future__ import annotations

import math

import numpy as np
import pytest

from daemon.guidance.clearance import forward_clearance_m
from daemon.guidance.cues import CueLimiter
from daemon.guidance.guide import Guidance, GuidanceOutput
from daemon.planning.grid import cell_to_xy
from daemon.planning.reference import ReferencePlanner
from protocol.messages import CuePriority, PatternKind, Pose

SHAPE = (60, 60)


def pose_at(cell: tuple[int, int], heading: float, t: float = 0.0) -> Pose:
    x, y = cell_to_xy(SHAPE, cell, 0.1)
    return Pose(x=x, y=y, heading=heading, stamp=t)


def straight_path(start: tuple[int, int], goal: tuple[int, int]) -> np.ndarray:
    p = ReferencePlanner()
    p.plan(np.zeros(SHAPE, dtype=bool), goal)
    return p.path(start)


def test_goal_to_the_east_while_facing_north_is_felt_on_the_right() -> None:
    g = Guidance()
    out = g.guide(straight_path((30, 10), (30, 50)), pose_at((30, 10), math.pi / 2), SHAPE, 0.0)
    assert isinstance(out, GuidanceOutput)
    assert out.pattern.kind is PatternKind.GUIDE
    assert out.pattern.motors == (0, 200, 0, 0)
    assert out.pattern.ttl_ms > 0
    assert out.cue is not None and out.cue.text == "turn to 3 o'clock, then 4 metres"
    assert out.target == pytest.approx(cell_to_xy(SHAPE, (30, 50), 0.1))


def test_straight_ahead_in_spanish() -> None:
    g = Guidance(lang="es")
    out = g.guide(straight_path((50, 30), (20, 30)), pose_at((50, 30), math.pi / 2), SHAPE, 0.0)
    assert out.pattern.motors == (200, 0, 0, 0)
    assert out.cue is not None and out.cue.text == "sigue recto, 3 metros" and out.cue.lang == "es"


def test_target_behind_gives_turn_around() -> None:
    g = Guidance()
    out = g.guide(straight_path((30, 30), (50, 30)), pose_at((30, 30), math.pi / 2), SHAPE, 0.0)
    assert out.pattern.kind is PatternKind.TURN_AROUND
    assert out.pattern.motors[2] == 255
    assert out.cue is not None and out.cue.text == "turn around"
    assert out.cue.priority is CuePriority.SAFETY


def test_arrived_no_path_and_events() -> None:
    g = Guidance()
    goal = (30, 30)
    out = g.guide(np.array([goal], dtype=np.int32), pose_at(goal, 0.0), SHAPE, 0.0)
    assert out.pattern.kind is PatternKind.ARRIVED and out.cue is not None
    assert out.cue.text == "arrived"
    none = g.guide(np.empty((0, 2), dtype=np.int32), pose_at(goal, 0.0), SHAPE, 1.0)
    assert none.pattern.kind is PatternKind.NO_PATH and none.cue.text == "no path to the goal"
    for kind in (PatternKind.STOP, PatternKind.REROUTE, PatternKind.WAIT, PatternKind.OFF):
        ev = g.event(kind, 10.0, reason="because")
        assert ev.pattern.kind is kind and ev.pattern.ttl_ms >= 50
    with pytest.raises(ValueError):
        g.event(PatternKind.GUIDE, 11.0)


def test_routine_cues_do_not_chatter_while_walking_a_straight_leg() -> None:
    g = Guidance(limiter=CueLimiter(min_interval_s=3.0, repeat_s=12.0))
    cues = []
    for step in range(25):  # 2.5 m up a straight corridor, one pose every 0.1 s
        cell = (50 - step, 30)
        out = g.guide(straight_path(cell, (5, 30)), pose_at(cell, math.pi / 2), SHAPE, step * 0.1)
        assert out.pattern.kind is PatternKind.GUIDE
        if out.cue is not None:
            cues.append(out.cue.text)
    assert cues == ["straight ahead, 5 metres"]


def test_a_new_leg_is_announced() -> None:
    blocked = np.zeros(SHAPE, dtype=bool)
    blocked[20:25, 5:55] = True
    blocked[10:40, 40:45] = True
    p = ReferencePlanner()
    p.plan(blocked, (5, 30))
    g = Guidance(limiter=CueLimiter(min_interval_s=0.0))
    first = g.guide(p.path((50, 30)), pose_at((50, 30), math.pi / 2), SHAPE, 0.0, blocked)
    assert first.cue is not None
    second = g.guide(p.path((50, 30)), pose_at((50, 30), math.pi / 2), SHAPE, 1.0, blocked)
    assert second.cue is None  # same leg, same hour
    path = p.path((50, 30))
    far = path[len(path) // 2]  # half way: the first turning point is behind, a new leg starts
    third = g.guide(p.path(tuple(far)), pose_at(tuple(far), math.pi / 2), SHAPE, 5.0, blocked)
    assert third.cue is not None


def test_pulses_near_an_obstacle_ahead_only() -> None:
    blocked = np.zeros(SHAPE, dtype=bool)
    blocked[20:23, :] = True
    user = np.array([26.5, 30.5])  # 0.35 m south of the wall's near edge
    ahead = forward_clearance_m(blocked, user, math.pi / 2, 0.1)
    behind = forward_clearance_m(blocked, user, -math.pi / 2, 0.1)
    assert ahead == pytest.approx(0.35, abs=0.06)
    assert behind is None
    g = Guidance()
    path = np.array([[26, c] for c in range(30, 50)], dtype=np.int32)
    near = g.guide(path, pose_at((26, 30), math.pi / 2), SHAPE, 0.0, blocked)
    assert near.pattern.period_ms > 0
    open_ground = g.guide(path, pose_at((26, 30), -math.pi / 2), SHAPE, 0.1, np.zeros_like(blocked))
    assert open_ground.pattern.period_ms == 0


def test_smoothing_option_guides_along_free_legs() -> None:
    blocked = np.zeros(SHAPE, dtype=bool)
    blocked[20:25, 10:50] = True
    p = ReferencePlanner()
    p.plan(blocked, (2, 30))
    g = Guidance(smooth=True)
    out = g.guide(p.path((55, 30)), pose_at((55, 30), math.pi / 2), SHAPE, 0.0, blocked)
    assert out.pattern.kind is PatternKind.GUIDE
    assert out.target is not None
