"""Hold instead of detour: wait for a block far ahead that just appeared, then go on."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from daemon.guidance.guide import Guidance
from daemon.guidance.hold import HoldPolicy, _direction
from daemon.planning.grid import cell_to_xy
from daemon.planning.inflation import InflatedMap
from daemon.planning.reference import ReferencePlanner
from protocol.messages import PatternKind, Pose
from sim.crossing import crossing_walk

SHAPE = (60, 40)
NORTH = math.pi / 2


def corridor(shut: bool = False) -> np.ndarray:
    """Blocked map (inflated by 0.3 m) of a corridor (cols 10-29) from row 20 to 55, open to
    the south, with a 1.2 m door at row 20 — or someone standing in the door (``shut``)."""
    occ = np.zeros(SHAPE, dtype=np.uint8)
    occ[20:56, 8:10] = 1
    occ[20:56, 30:32] = 1
    occ[20:22, 8:32] = 1
    occ[20:22, 14:26] = 0  # the doorway
    if shut:
        occ[19:23, 18:22] = 1
    return InflatedMap(occ, 3).blocked


def pose(cell: tuple[int, int], t: float) -> Pose:
    x, y = cell_to_xy(SHAPE, cell, 0.1)
    return Pose(x=x, y=y, heading=NORTH, stamp=t)


def plan(blocked: np.ndarray, start: tuple[int, int]) -> np.ndarray:
    p = ReferencePlanner()
    p.plan(blocked, (5, 20))
    return p.path(start)


def test_a_new_block_far_ahead_gives_wait_then_the_walk_goes_on() -> None:
    g = Guidance(hold=HoldPolicy(hold_s=4.0, far_m=1.5))
    user = (45, 20)
    open_map = corridor()
    assert g.guide(plan(open_map, user), pose(user, 0.0), SHAPE, 0.0, open_map).pattern.kind is (
        PatternKind.GUIDE
    )
    shut = corridor(shut=True)  # someone stands in the doorway, 2.4 m ahead
    detour = plan(shut, user)
    assert detour[1][0] > user[0]  # the planner would send the user back south
    out = g.guide(detour, pose(user, 0.5), SHAPE, 0.5, shut)
    assert out.pattern.kind is PatternKind.WAIT and out.cue is not None
    assert out.cue.text == "wait"
    assert g.guide(detour, pose(user, 2.0), SHAPE, 2.0, shut).pattern.kind is PatternKind.WAIT
    # the doorway clears within the hold: straight on, no detour
    resumed = g.guide(plan(open_map, user), pose(user, 3.0), SHAPE, 3.0, open_map)
    assert resumed.pattern.kind is PatternKind.GUIDE
    assert resumed.pattern.motors[0] > 0
    assert g.hold.holds == 1


def test_the_detour_is_taken_when_the_hold_runs_out() -> None:
    g = Guidance(hold=HoldPolicy(hold_s=3.0))
    user = (45, 20)
    g.guide(plan(corridor(), user), pose(user, 0.0), SHAPE, 0.0, corridor())
    shut = corridor(shut=True)
    detour = plan(shut, user)
    kinds = [g.guide(detour, pose(user, t), SHAPE, t, shut).pattern.kind for t in (0.5, 2.0, 3.6)]
    assert kinds == [PatternKind.WAIT, PatternKind.WAIT, PatternKind.REROUTE]
    after = g.guide(detour, pose(user, 4.0), SHAPE, 4.0, shut)
    assert after.pattern.kind is PatternKind.TURN_AROUND  # only one hold per blockage
    assert g.hold.holds == 1


def test_a_near_block_is_not_worth_a_hold() -> None:
    g = Guidance(hold=HoldPolicy(far_m=1.5))
    user = (28, 20)  # 0.6 m from the doorway
    g.guide(plan(corridor(), user), pose(user, 0.0), SHAPE, 0.0, corridor())
    shut = corridor(shut=True)
    out = g.guide(plan(shut, user), pose(user, 0.5), SHAPE, 0.5, shut)
    assert out.pattern.kind is PatternKind.TURN_AROUND
    assert g.hold.holds == 0


def test_an_old_block_is_not_worth_a_hold() -> None:
    g = Guidance(hold=HoldPolicy(recent_s=2.0))
    user = (45, 20)
    g.guide(plan(corridor(), user), pose(user, 0.0), SHAPE, 0.0, corridor())
    shut = corridor(shut=True)
    out = g.guide(plan(shut, user), pose(user, 10.0), SHAPE, 10.0, shut)
    assert out.pattern.kind is PatternKind.TURN_AROUND


@pytest.mark.timeout(60)
def test_moving_obstacle_scenario_hold_saves_the_detour() -> None:
    held = crossing_walk(hold=True, seed=1)
    detoured = crossing_walk(hold=False, seed=1)
    assert held.arrived and detoured.arrived
    assert held.collisions == 0 and detoured.collisions == 0
    assert held.holds == 1 and detoured.holds == 0
    assert held.backtrack_m < 0.3  # never turned round
    assert detoured.backtrack_m > 1.0  # turned round and walked back
    assert held.walked_m < 0.7 * detoured.walked_m
    assert held.time_s < detoured.time_s


@settings(max_examples=300, deadline=None)
@given(
    steps=st.lists(st.tuples(st.integers(-1, 1), st.integers(-1, 1)), min_size=1, max_size=60),
    user=st.tuples(st.floats(30, 70), st.floats(30, 70)),
    ahead=st.floats(0, 40),
)
def test_the_compiled_direction_equals_numpys_to_the_bit(steps, user, ahead):
    """The direction along a path, as numpy wrote it before it was compiled (same sums)."""
    path = np.cumsum(np.array(steps, np.int64), axis=0) + 50
    user_rc = np.array(user)
    want = None
    if len(path) >= 2:
        centres = path.astype(np.float64) + 0.5
        start = int(np.argmin(np.hypot(*(centres - user_rc).T)))
        seg = np.hypot(*np.diff(centres[start:], axis=0).T)
        if seg.size:
            k = start + 1 + min(int(np.searchsorted(np.cumsum(seg), ahead)), seg.size - 1)
            d = centres[k] - centres[start]
            want = math.atan2(-d[0], d[1])
    assert _direction(path, user_rc, ahead) == want
