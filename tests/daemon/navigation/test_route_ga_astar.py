"""The navigator with the GA+A* planner answers bad input with the statuses and belt patterns
EDS gives: no path, a goal in an obstacle or off the map, a pose off the map."""

from __future__ import annotations

import time

import numpy as np
import pytest

from daemon.navigation import Inbox, Navigator, NavigatorSettings
from protocol.messages import Goal, GoalCell, MapDelta, PatternKind, Pose, StatusCode

SHAPE = (30, 30)


def pose(cell: tuple[int, int], far: float | None = None) -> Pose:
    r, c = cell
    x, y = (c + 0.5) / 10, (SHAPE[0] - r - 0.5) / 10
    return Pose(x=far or x, y=far or y, heading=1.57, stamp=time.time())


def goal(row: int, col: int) -> Goal:
    return Goal(target=GoalCell(row=row, col=col), stamp=time.time())


def answers(planner: str) -> list[tuple[list[str], list[PatternKind], bool]]:
    """(status codes, belt patterns, a path given?) of each step of one bad-input sequence."""
    nav = Navigator("u", NavigatorSettings(backend="cpu", planner=planner))
    wall = 10 * SHAPE[1] + np.arange(SHAPE[1])
    gap = wall[:8]
    # Each step's messages are made when it runs: a pose stamped before a slow step (a cold
    # compile in a fresh checkout) would be stale by its turn, and STOP is the right answer.
    steps = [
        lambda: Inbox(deltas=[MapDelta.from_arrays(0, SHAPE, wall, np.ones(wall.size, np.uint8),
                                           time.time())],
              goal=goal(3, 15), pose=pose((26, 15))),  # a wall across the map: no path
        lambda: Inbox(deltas=[MapDelta.from_arrays(1, SHAPE, gap, np.zeros(gap.size, np.uint8),
                                           time.time())],
              pose=pose((26, 15))),  # a gap opens: guide
        lambda: Inbox(pose=pose((25, 14))),
        lambda: Inbox(goal=goal(10, 20), pose=pose((25, 14))),  # the goal in the wall
        lambda: Inbox(goal=goal(3, 15), pose=pose((25, 14), far=9e5)),  # the pose off the map
        lambda: Inbox(goal=goal(3, 15), pose=pose((25, 14))),
    ]  # fmt: skip
    out = []
    for make in steps:
        o = nav.step(make(), time.time())
        given = o.path_cells is not None and len(o.path_cells) > 0
        # OK statuses also come as a once-a-second refresh: when they fall depends on how long
        # each planner took, so only the codes of trouble are compared.
        out.append(([str(s.code) for s in o.statuses if s.code], [b.kind for b in o.belt], given))
    return out


@pytest.mark.timeout(60)
def test_bad_input_gives_the_statuses_and_patterns_eds_gives():
    eds, ga = answers("eds"), answers("ga-astar")
    assert [(codes, kinds) for codes, kinds, _ in ga] == [(c, k) for c, k, _ in eds]
    assert [g for *_, g in ga] == [g for *_, g in eds]
    codes = [c for codes, _, _ in ga for c in codes]
    for expected in (StatusCode.NO_PATH, StatusCode.GOAL_IN_OBSTACLE, StatusCode.POSE_OFF_MAP):
        assert str(expected) in codes
    assert PatternKind.GUIDE in ga[1][1] and ga[1][2]  # the gap: guided along a path
