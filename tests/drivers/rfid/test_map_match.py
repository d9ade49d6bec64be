"""A bump and the camera's nearest obstacle as measurements of the position, against the map."""

from __future__ import annotations

import math

import numpy as np
import pytest

from drivers.rfid.map_match import (
    MIN_SIGMA_M,
    Z_OFF_FREE,
    contact_likelihood,
    free_space_likelihood,
    grid_measurement,
    obstacle_likelihood,
)
from drivers.rfid.pose_filter import PoseFilter
from drivers.rfid.protocol import Read
from drivers.rfid.tags import Tag, TagMap, TagMapFile

CELL = 0.1


def wall_map() -> np.ndarray:
    """A 6 x 6 m room, free, with a wall along x = 4.0..4.2 m (cols 40-41), y 1..5 m."""
    grid = np.zeros((60, 60), dtype=np.uint8)
    grid[10:50, 40:42] = 1
    return grid


def tags() -> TagMap:
    spread = [(0.5, 0.5), (5.5, 0.5), (0.5, 5.5)]
    uhf = [Tag(id=f"AAAA000{i}", kind="uhf", x=x, y=y) for i, (x, y) in enumerate(spread)]
    lf = [Tag(id="BBBB0001", kind="lf", x=3.0, y=3.0), Tag(id="BBBB0002", kind="lf", x=3.2, y=3.0)]
    return TagMap(TagMapFile(width_m=6.0, height_m=6.0, tags=uhf + lf))


def test_a_bump_moves_the_estimate_to_where_a_step_meets_the_wall() -> None:
    # Truly at x = 3.65 (a 0.5 m step east meets the wall at 4.0); the estimate says 3.2.
    f = PoseFilter(tags(), start=(3.2, 3.0), start_sigma_m=0.3, pedometer=True)
    f.compass(0.0, 0.0)  # facing east
    like = contact_likelihood(wall_map(), CELL, heading=0.0, reach_m=0.5)
    assert like(np.array([[3.65, 3.0], [3.2, 3.0]])).tolist() == [1.0, pytest.approx(0.01)]
    assert f.constrain(0.1, like)
    pose = f.pose(0.1)
    assert pose is not None and 3.45 <= pose.x <= 3.95  # within a step of the wall
    assert pose.y == pytest.approx(3.0, abs=0.05)  # the wall says nothing along itself
    cov = f.P[:2, :2]
    assert cov[0, 0] < 0.3**2 / 2 and cov[1, 1] == pytest.approx(0.3**2, rel=0.05)


def test_the_cameras_nearest_obstacle_puts_the_user_its_distance_from_the_wall() -> None:
    # The camera sees the wall's edge 0.6 m straight ahead: x = 4.0 − 0.6 = 3.4.
    like = obstacle_likelihood(wall_map(), CELL, heading=0.0, nearest_m=0.6, bearing=0.0)
    xs = np.array([[3.0, 3.0], [3.4, 3.0], [3.5, 3.0], [3.9, 3.0]])
    assert like(xs).tolist() == pytest.approx([0.1, 1.08, 1.08, 0.1], abs=0.01)
    f = PoseFilter(tags(), start=(3.25, 3.0), start_sigma_m=0.15, pedometer=True)
    f.compass(0.0, 0.0)
    assert f.constrain(0.1, like)
    pose = f.pose(0.1)
    assert pose is not None and 3.3 < pose.x < 3.5  # pulled from 3.25 towards 3.4
    assert pose.y == pytest.approx(3.0, abs=0.02)
    assert f.P[0, 0] < 0.15**2 * 0.8 and f.P[1, 1] == pytest.approx(0.15**2, rel=0.05)
    # Never more than MIN_SIGMA_M sure along any direction, however sharp the grid's posterior.
    got = grid_measurement(np.array([3.45, 3.0]), np.diag([0.1, 0.1]) ** 2, like)
    assert got is not None and np.all(np.diag(got[2]) >= MIN_SIGMA_M**2 - 1e-12)


def test_a_match_the_map_cannot_explain_says_nothing() -> None:
    free = np.zeros((60, 60), dtype=np.uint8)
    like = obstacle_likelihood(free, CELL, heading=0.0, nearest_m=0.6, bearing=0.0)
    assert grid_measurement(np.array([3.0, 3.0]), np.eye(2) * 0.04, like) is None
    f = PoseFilter(tags())  # no position yet: nothing to constrain
    assert not f.constrain(0.0, contact_likelihood(wall_map(), CELL, 0.0, 0.5))


def test_standing_on_a_signpost_does_not_make_the_filter_surer_and_surer() -> None:
    f = PoseFilter(tags(), start=(3.0, 3.0), start_sigma_m=0.3, pedometer=True)
    for k in range(250):  # five seconds of LF rounds at 50 a second, standing still
        f.add(Read("BBBB0001", -40.0, 0.02 * k))
        f.pose(0.02 * k + 0.01)
    # One tag's 10 cm: about 5 cm however often it is read (it was 3 mm before).
    assert f.sigma_m > 0.035
    assert math.isfinite(f.sigma_m)


def test_the_user_stands_on_free_floor_and_the_maps_edge_is_no_wall() -> None:
    stand = free_space_likelihood(wall_map(), CELL)
    pts = np.array([[3.0, 3.0], [4.1, 3.0], [-0.2, 3.0], [3.0, 6.3]])  # free, wall, off, off
    assert stand(pts).tolist() == [1.0, Z_OFF_FREE, Z_OFF_FREE, Z_OFF_FREE]
    # An estimate drifted into a block (east of x = 4 m) is put back out of it, across
    # the block's face only. (Inside a thin wall the posterior has two humps and a mean
    # in the wall: no Gaussian says that, and nothing is constrained.)
    block = np.zeros((60, 60), dtype=np.uint8)
    block[:, 40:] = 1
    f = PoseFilter(tags(), start=(4.1, 3.0), start_sigma_m=0.2, pedometer=True)
    assert f.constrain(0.1, free_space_likelihood(block, CELL))
    pose = f.pose(0.1)
    assert pose is not None and pose.x < 4.0
    assert pose.y == pytest.approx(3.0, abs=0.05)
    assert f.P[0, 0] < 0.2**2 / 2 and f.P[1, 1] == pytest.approx(0.2**2, rel=0.05)
    # Facing south from near the south edge, a step meets nothing: the map's edge beyond
    # is not a hit (it drew an estimate by a wall out through it), and off the map is no
    # place to stand.
    like = contact_likelihood(wall_map(), CELL, heading=-math.pi / 2, reach_m=0.5)
    near_edge = like(np.array([[1.0, 0.3], [1.0, -0.3]]))
    assert near_edge.tolist() == pytest.approx([0.01, 0.01 * Z_OFF_FREE])
