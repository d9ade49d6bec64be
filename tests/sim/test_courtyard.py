"""The simulated courtyard: seeded, connected, covering what was asked."""

from __future__ import annotations

import numpy as np
import pytest

from daemon.planning.dijkstra import dijkstra_field
from daemon.planning.grid import FREE, INF, OCCUPIED, UNKNOWN
from daemon.planning.inflation import InflatedMap
from sim.courtyard import base_courtyard, connected, dilate, make_courtyard

pytestmark = pytest.mark.timeout(60)


def test_same_seed_same_scenario_other_seed_other_blobs():
    a = make_courtyard(grid=100, unknown=0.4, seed=7)
    b = make_courtyard(grid=100, unknown=0.4, seed=7)
    c = make_courtyard(grid=100, unknown=0.4, seed=8)
    assert np.array_equal(a.true, b.true) and np.array_equal(a.known, b.known)
    assert (a.start, a.goal) == (b.start, b.goal)
    assert np.array_equal(a.known, c.known)
    assert not np.array_equal(a.true, c.true)


@pytest.mark.parametrize("grid", [50, 100, 200])
@pytest.mark.parametrize("unknown", [0.2, 0.4, 0.6])
def test_start_and_goal_connected_in_the_inflated_true_map(grid, unknown):
    s = make_courtyard(grid=grid, unknown=unknown, seed=1)
    blocked = InflatedMap(s.true, s.radius_cells).blocked
    assert not blocked[s.start] and not blocked[s.goal]
    if grid <= 100:  # the reference Dijkstra is pure Python: keep it to small maps
        assert dijkstra_field(blocked, s.goal)[s.start] < INF
    assert connected(blocked, s.start, s.goal)
    assert s.start[0] > 0.9 * grid and s.goal[0] < 0.1 * grid  # start south, goal north


@pytest.mark.parametrize("unknown", [0.0, 0.2, 0.4, 0.6])
def test_blobs_cover_the_asked_fraction_of_the_free_area(unknown):
    s = make_courtyard(grid=100, unknown=unknown, seed=2)
    free = s.known != OCCUPIED
    measured = np.count_nonzero(free & (s.true == OCCUPIED)) / np.count_nonzero(free)
    assert measured == pytest.approx(s.coverage)
    assert abs(s.coverage - unknown) < 0.02


def test_maps_hold_the_grid_values_and_known_obstacles_are_true_ones():
    s = make_courtyard(grid=100, unknown=0.4, seed=3)
    assert s.known.dtype == np.uint8 and s.true.dtype == np.uint8
    assert set(np.unique(s.known)) <= {OCCUPIED, UNKNOWN}
    assert set(np.unique(s.true)) <= {FREE, OCCUPIED}
    assert np.all(s.true[s.known == OCCUPIED] == OCCUPIED)
    assert np.array_equal(s.known, base_courtyard())
    # outer walls
    assert np.all(s.known[0] == OCCUPIED) and np.all(s.known[:, -1] == OCCUPIED)


def test_finer_grids_are_the_same_courtyard_at_finer_cells():
    s1 = make_courtyard(grid=100, unknown=0.4, seed=4)
    s2 = make_courtyard(grid=200, unknown=0.4, seed=4)
    assert s2.cell_m == pytest.approx(s1.cell_m / 2)
    assert s2.radius_cells == 2 * s1.radius_cells
    assert s2.sensor_range_cells == pytest.approx(2 * s1.sensor_range_cells)
    assert np.array_equal(s2.known, np.repeat(np.repeat(s1.known, 2, 0), 2, 1))
    assert np.array_equal(s2.true, np.repeat(np.repeat(s1.true, 2, 0), 2, 1))


@pytest.mark.parametrize("radius", [0, 1, 3, 6])
def test_dilate_equals_the_inflated_map(radius):
    rng = np.random.default_rng(radius)
    occ = (rng.random((40, 57)) < 0.05).astype(np.uint8)
    assert np.array_equal(dilate(occ == OCCUPIED, radius), InflatedMap(occ, radius).blocked)


def test_connected_sees_a_cut():
    blocked = np.zeros((10, 10), dtype=bool)
    assert connected(blocked, (9, 0), (0, 9))
    blocked[5, :] = True
    assert not connected(blocked, (9, 0), (0, 9))
    blocked[5, 9] = False
    assert connected(blocked, (9, 0), (0, 9))


@pytest.mark.parametrize("grid", [0, 30, 150])
def test_grid_sides_that_are_not_the_courtyard_are_refused(grid):
    with pytest.raises(ValueError):
        make_courtyard(grid=grid)
