"""New route, off route and the countdown: what the user is told when the way ahead changes."""

from __future__ import annotations

import math

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from daemon.guidance.guide import Guidance
from daemon.guidance.route_watch import RouteWatch, _nearest_m, _sampled
from protocol.messages import PatternKind, Pose
from sim.closed_loop import route_departs

NORTH = math.pi / 2
SHAPE = (60, 60)


def line(r0: int, c0: int, r1: int, c1: int) -> np.ndarray:
    n = max(abs(r1 - r0), abs(c1 - c0))
    return np.stack([np.rint(np.linspace(r0, r1, n + 1)), np.rint(np.linspace(c0, c1, n + 1))],
                    axis=1).astype(np.int32)  # fmt: skip


def north_then(c: int) -> np.ndarray:
    """From (50, 30) north to row 35, then across to column ``c`` and on north to row 5."""
    return np.vstack([line(50, 30, 35, 30), line(35, 30, 35, c)[1:], line(35, c, 5, c)[1:]])


def test_the_route_watch_tells_a_new_route_from_a_straighter_one_and_an_excursion() -> None:
    w = RouteWatch()
    straight = line(50, 30, 5, 30)
    assert w.check(straight, 0.1) is None  # nothing to compare with yet
    w.keep(straight, 0.1)
    # A corner cut by a cell or two is the same route.
    assert w.check(north_then(31), 0.1) is None
    # The way ahead now turns 2 m east within the next 3 m: a new route.
    east = np.vstack([line(50, 30, 48, 30), line(48, 30, 48, 50)[1:]])
    assert w.check(east, 0.1) == "new_route"
    # A user 1.5 m east of the kept route is off it: said once, until back near it.
    off = line(40, 45, 5, 45)
    assert w.check(off, 0.1) == "off_route"
    assert w.check(off, 0.1) is None
    assert w.check(line(45, 31, 5, 31), 0.1) is None  # back on the route: re-armed
    assert w.check(off, 0.1) == "off_route"


def test_the_walks_independent_check_counts_the_same_changes() -> None:
    straight = line(50, 30, 5, 30)
    assert not route_departs(straight, north_then(31), 0.1)
    assert route_departs(straight, np.vstack([line(50, 30, 48, 30), line(48, 30, 48, 50)[1:]]), 0.1)
    # A change beyond 3 m of the user is not the way ahead yet.
    assert not route_departs(straight, np.vstack([line(50, 30, 15, 30), line(15, 30, 15, 55)[1:]]),
                             0.1)  # fmt: skip


def guide(g: Guidance, path: np.ndarray, t: float, heading: float = NORTH):
    r, c = int(path[0][0]), int(path[0][1])
    pose = Pose(x=(c + 0.5) * 0.1, y=(SHAPE[0] - r - 0.5) * 0.1, heading=heading, stamp=t)
    return g.guide(path, pose, SHAPE, t, np.zeros(SHAPE, dtype=bool))


def test_a_new_route_is_announced_at_once_with_its_direction_and_the_reroute_pattern() -> None:
    g = Guidance(cell_m=0.1)
    first = guide(g, line(50, 30, 5, 30), 0.0)
    assert first.pattern.kind is PatternKind.GUIDE and first.cue is not None
    out = guide(g, np.vstack([line(50, 30, 49, 30), line(49, 30, 49, 55)[1:],
                              line(49, 55, 5, 55)[1:]]), 0.6)  # fmt: skip
    assert out.pattern.kind is PatternKind.REROUTE
    assert out.cue is not None and out.cue.kind == "new_route"
    # Across the empty map the way goes straight for the far corner, ahead and to the right.
    assert out.cue.text in ("new route, turn to 1 o'clock, then 5 metres",)
    # The next step on the same route: guided again, nothing more to announce.
    assert guide(g, np.vstack([line(49, 31, 49, 55), line(49, 55, 5, 55)[1:]]), 1.2,
                 heading=0.0).pattern.kind is PatternKind.GUIDE  # fmt: skip


def test_the_last_leg_counts_down_to_the_goal() -> None:
    g = Guidance(cell_m=0.1)
    said = []
    for i, r in enumerate(range(58, 20, -1)):  # straight north to the goal at row 5
        out = guide(g, line(r, 30, 5, 30), 0.6 * i)
        if out.cue is not None:
            said.append(out.cue.text)
    assert "goal in 5 metres" in said and "goal in 2 metres" in said
    assert said.count("goal in 5 metres") == 1


def test_a_long_leg_is_reassured_at_the_configured_interval_and_not_when_off() -> None:
    def step(g: Guidance, row: int, t: float):  # 20 cm cells: a leg of 8 m north
        pose = Pose(x=30.5 * 0.2, y=(SHAPE[0] - row - 0.5) * 0.2, heading=NORTH, stamp=t)
        return g.guide(line(row, 30, 5, 30), pose, SHAPE, t, np.zeros(SHAPE, dtype=bool))

    for every, want in ((4.0, 2), (0.0, 0)):
        g = Guidance(cell_m=0.2, reassure_s=every)
        assert step(g, 58, 0.0).cue is not None  # "straight ahead, 8 metres": the first cue
        again = [step(g, 58 - i, 0.6 * i).cue for i in range(1, 16)]
        texts = [c.text for c in again if c is not None and c.kind == "direction"]
        assert len(texts) == want, texts
        assert all(t.startswith("straight ahead") for t in texts)


@settings(max_examples=200, deadline=None)
@given(
    points=st.lists(st.tuples(st.floats(0, 100), st.floats(0, 100)), min_size=1, max_size=30),
    route=st.lists(st.tuples(st.floats(0, 100), st.floats(0, 100)), min_size=1, max_size=80),
)
def test_the_compiled_nearest_distance_equals_numpys_to_the_bit(points, route):
    p, r = np.array(points), np.array(route)
    d = p[:, None, :] - r[None, :, :]
    want = np.sqrt((d * d).sum(axis=2)).min(axis=1) * 0.05
    assert np.array_equal(_nearest_m(p, r, 0.05), want)


def test_sampling_keeps_every_step_th_cell_and_the_end():
    for cell_m in (0.1, 0.05, 0.03):
        step = max(1, math.ceil(0.1 / cell_m))
        for n in range(12):
            path = np.array([(r, 2 * r) for r in range(n)], np.int64).reshape(-1, 2)
            want = [tuple(path[i]) for i in range(0, n, step)]
            if n and (n - 1) % step:
                want.append(tuple(path[-1]))
            got = _sampled(path, cell_m)
            assert got.dtype == np.float64 and got.shape == (len(want), 2)
            assert [tuple(p) for p in got.astype(np.int64)] == want


def test_the_route_kept_after_a_check_is_the_path_checked():
    a, b = RouteWatch(), RouteWatch()
    first = np.array([(r, 5) for r in range(40, 0, -1)])
    second = np.array([(40, c) for c in range(5, 30)] + [(r, 29) for r in range(39, 0, -1)])
    for w in (a, b):
        w.keep(first, 0.05)
    assert a.check(second, 0.05) == b.check(second, 0.05)
    a.keep(second, 0.05)  # after the check: its samples
    b.reset()
    b.keep(second, 0.05)  # afresh
    assert np.array_equal(a._last, b._last)
    a.check(first, 0.05)
    a.keep(second, 0.05)  # another path than the one checked: sampled afresh
    assert np.array_equal(a._last, b._last)
