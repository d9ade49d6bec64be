"""Turning points: line of sight, end-point fit, any-angle shortcuts, eq. 6 headings."""

from __future__ import annotations

import itertools
import math

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from daemon.guidance.turning_points import (
    bearing,
    douglas_peucker,
    is_core,
    relative_angle,
    segment_clear,
    segment_free,
    turning_points,
    xy_to_continuous,
)
from daemon.planning.grid import cell_to_xy
from daemon.planning.inflation import InflatedMap
from daemon.planning.reference import ReferencePlanner


def dense_hits(blocked: np.ndarray, a: tuple, b: tuple, n: int = 4000) -> bool:
    t = np.linspace(0.0, 1.0, n)
    r = a[0] + t * (b[0] - a[0])
    c = a[1] + t * (b[1] - a[1])
    return bool(blocked[np.floor(r).astype(int), np.floor(c).astype(int)].any())


@settings(max_examples=150, deadline=None)
@given(
    st.integers(0, 2**31 - 1),
    st.tuples(*[st.floats(0.01, 19.99) for _ in range(4)]),
)
def test_segment_free_never_misses_a_blocked_cell(seed: int, seg: tuple) -> None:
    blocked = np.random.default_rng(seed).random((20, 20)) < 0.15
    r0, c0, r1, c1 = seg
    if segment_free(blocked, r0, c0, r1, c1):
        assert not dense_hits(blocked, (r0, c0), (r1, c1))


@settings(max_examples=150, deadline=None)
@given(
    st.integers(0, 2**31 - 1),
    st.sampled_from([2, 3, 6]),
    st.tuples(*[st.floats(0.01, 39.99) for _ in range(4)]),
)
def test_a_line_that_shaves_the_margin_never_reaches_an_obstacle(
    seed: int, radius: int, seg: tuple
) -> None:
    occ = (np.random.default_rng(seed).random((40, 40)) < 0.01).astype(np.uint8)
    blocked = InflatedMap(occ, radius).blocked
    r0, c0, r1, c1 = seg
    if segment_clear(blocked, r0, c0, r1, c1, int(0.5 * radius)):
        assert not dense_hits(occ.astype(bool), (r0, c0), (r1, c1))


def test_segment_clear_shaves_only_the_outer_margin() -> None:
    occ = np.zeros((20, 20), dtype=np.uint8)
    occ[10, 10] = 1
    blocked = InflatedMap(occ, 3).blocked
    # a line through the margin's edge, 3 cells from the obstacle
    assert not segment_free(blocked, 7.5, 0.5, 7.5, 19.5)
    assert segment_clear(blocked, 7.5, 0.5, 7.5, 19.5, 1)
    assert not segment_clear(blocked, 10.5, 0.5, 10.5, 19.5, 1)
    assert is_core(blocked, 10, 10, 1) and not is_core(blocked, 7, 10, 1)


def test_segment_free_basics() -> None:
    b = np.zeros((10, 10), dtype=bool)
    b[5, 5] = True
    assert segment_free(b, 0.5, 0.5, 9.5, 0.5)
    assert not segment_free(b, 5.5, 0.5, 5.5, 9.5)
    assert not segment_free(b, 0.5, 0.5, 9.5, 9.5)  # the diagonal through (5, 5)
    assert not segment_free(b, 0.5, 0.5, 10.5, 0.5)  # off the map
    # a diagonal step between two blocked corner cells touches them at one point only
    c = np.zeros((4, 4), dtype=bool)
    c[1, 2] = c[2, 1] = True
    assert segment_free(c, 1.5, 1.5, 2.5, 2.5)


def test_douglas_peucker_keeps_the_corner_of_an_l() -> None:
    pts = np.array([[r, 0] for r in range(10)] + [[9, c] for c in range(1, 10)], dtype=float)
    keep = douglas_peucker(pts, 0.5)
    assert pts[keep].tolist() == [[0, 0], [9, 0], [9, 9]]
    zigzag = np.array([[0, 0], [1, 1], [1, 2], [2, 3], [2, 4], [3, 5]], dtype=float)
    assert len(douglas_peucker(zigzag, 0.75)) == 2


def test_open_ground_needs_no_turning_point() -> None:
    blocked = np.zeros((40, 40), dtype=bool)
    p = ReferencePlanner()
    p.plan(blocked, (2, 30))
    path = p.path((37, 5))  # an 8-connected path: a diagonal run then a straight one
    pts = turning_points(path, blocked)
    assert len(pts) == 2  # any angle: straight from the user to the goal
    assert len(turning_points(path)) == 3  # without the map: the grid path's one real corner


def test_turning_points_go_round_an_obstacle_with_free_legs() -> None:
    blocked = np.zeros((60, 60), dtype=bool)
    blocked[20:25, 10:50] = True
    p = ReferencePlanner()
    p.plan(blocked, (2, 30))
    path = p.path((55, 30))
    pts = turning_points(path, blocked)
    assert 3 <= len(pts) <= 5
    assert np.allclose(pts[0], path[0] + 0.5) and np.allclose(pts[-1], path[-1] + 0.5)
    for a, b in itertools.pairwise(pts):
        assert segment_free(blocked, a[0], a[1], b[0], b[1])
    assert turning_points(np.empty((0, 2), dtype=np.int32), blocked).shape == (0, 2)


def test_max_leg_splits_long_legs() -> None:
    blocked = np.zeros((100, 10), dtype=bool)
    path = np.array([[r, 5] for r in range(99, -1, -1)], dtype=np.int32)
    pts = turning_points(path, blocked, max_leg_cells=30)
    legs = np.hypot(*np.diff(pts, axis=0).T)
    assert legs.max() <= 30 + 1e-9


def test_bearing_is_eq6_in_the_grid_frame() -> None:
    shape = (10, 10)
    here = np.array([5.5, 5.5])
    assert bearing(shape, here, np.array([5.5, 8.5])) == 0.0  # east
    assert math.isclose(bearing(shape, here, np.array([2.5, 5.5])), math.pi / 2)  # north
    assert math.isclose(bearing(shape, here, np.array([8.5, 2.5])), -3 * math.pi / 4)


def test_relative_angle_is_ccw_positive_and_wrapped() -> None:
    assert math.isclose(relative_angle(math.pi / 2, 0.0), math.pi / 2)  # to the left
    assert math.isclose(relative_angle(0.0, math.pi / 2), -math.pi / 2)  # to the right
    assert math.isclose(relative_angle(-3.0, 3.0), 2 * math.pi - 6.0)
    assert relative_angle(math.pi, 0.0) == math.pi


def test_metres_and_continuous_cells_agree_with_grid() -> None:
    shape = (30, 40)
    x, y = cell_to_xy(shape, (7, 12), 0.1)
    assert np.allclose(xy_to_continuous(shape, x, y, 0.1), [7.5, 12.5])
