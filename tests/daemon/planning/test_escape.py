"""The way out of the inflation margin leads to the nearest free cell, never across an obstacle."""

from __future__ import annotations

import numpy as np

from daemon.planning import make_planner
from daemon.planning.escape import escape_path
from daemon.planning.grid import INF, OCCUPIED, path_cost
from daemon.planning.inflation import InflatedMap

USER, GOAL = (12, 15), (3, 15)


def wall_map(gap: bool) -> tuple[InflatedMap, object]:
    """A thin wall, the goal above it, the user just below it (inside its margin)."""
    occ = np.zeros((30, 40), np.uint8)
    occ[10, :] = OCCUPIED
    if gap:
        occ[10, 30:] = 0  # a way round on the right, far from the user
    m = InflatedMap(occ, 3)
    planner = make_planner("eds", "cpu")
    planner.plan(m.blocked, GOAL)
    assert m.blocked[USER]
    return m, planner


def test_the_lead_goes_to_the_nearest_free_cell_with_a_path():
    m, planner = wall_map(gap=True)
    # Reach wide enough that free cells beyond the wall, much cheaper, are in the window.
    path, cost = escape_path(planner, m.blocked, m.occupancy, USER, reach=12)
    assert tuple(path[0]) == USER and tuple(path[-1]) == GOAL
    first_free = next(i for i, c in enumerate(path) if not m.blocked[tuple(c)])
    assert tuple(path[first_free]) == (14, 15)  # two steps straight down: the nearest way out
    assert all(m.occupancy[tuple(c)] != OCCUPIED for c in path)
    assert cost == 2 * 10 + planner.cost_at((14, 15))
    assert path_cost(path[first_free:]) == planner.cost_at((14, 15))


def test_an_exit_only_across_the_wall_is_refused():
    m, planner = wall_map(gap=False)  # below the wall nothing reaches the goal
    path, cost = escape_path(planner, m.blocked, m.occupancy, USER, reach=12)
    assert path.shape == (0, 2) and cost == int(INF)


def test_no_free_cell_within_reach_gives_no_path():
    m, planner = wall_map(gap=True)
    path, cost = escape_path(planner, m.blocked, m.occupancy, USER, reach=1)
    assert path.shape == (0, 2) and cost == int(INF)


def test_an_estimate_on_an_occupied_cell_is_led_out_of_that_obstacle_only():
    # 60 %, seed 43 with RFID alone: an LF patch pinned the estimate onto a blob seen beside
    # the user; every lead began on an occupied cell, and the user stood at NO_PATH for good.
    occ = np.zeros((30, 40), np.uint8)
    occ[14:17, 14:17] = OCCUPIED  # the blob under the estimate
    occ[10, :] = OCCUPIED  # a wall above it, the goal beyond a gap on the right
    occ[10, 30:] = 0
    m = InflatedMap(occ, 3)
    planner = make_planner("eds", "cpu")
    planner.plan(m.blocked, GOAL)
    user = (15, 15)
    path, cost = escape_path(planner, m.blocked, m.occupancy, user, reach=12)
    assert tuple(path[0]) == user and tuple(path[-1]) == GOAL and cost < int(INF)
    hit = [m.occupancy[tuple(c)] == OCCUPIED for c in path]
    out = hit.index(False)
    assert not any(hit[out:])  # once out of the blob, never into an obstacle again
    assert out <= 2  # straight out of the blob's nearest side
    # A way that would cross the wall to leave is still refused.
    walled = occ.copy()
    walled[10, 30:] = OCCUPIED
    m2 = InflatedMap(walled, 3)
    planner.plan(m2.blocked, GOAL)
    path, cost = escape_path(planner, m2.blocked, m2.occupancy, user, reach=12)
    assert path.shape == (0, 2) and cost == int(INF)


def test_an_estimate_deep_in_a_thick_obstacle_is_not_led_through_it():
    # Four cells in from every side of a 9 x 9 block: no user stands there, and any way out
    # would cross more of the obstacle than an estimate pinned beside it can explain.
    occ = np.zeros((30, 40), np.uint8)
    occ[11:20, 11:20] = OCCUPIED
    m = InflatedMap(occ, 3)
    planner = make_planner("eds", "cpu")
    planner.plan(m.blocked, GOAL)
    path, cost = escape_path(planner, m.blocked, m.occupancy, (15, 15), reach=12)
    assert path.shape == (0, 2) and cost == int(INF)
    # Three cells in from its nearest side: led out that way, never through the rest.
    path, cost = escape_path(planner, m.blocked, m.occupancy, (13, 15), reach=12)
    assert tuple(path[-1]) == GOAL and cost < int(INF)
    hit = [m.occupancy[tuple(c)] == OCCUPIED for c in path]
    assert hit.index(False) <= 3 and not any(hit[hit.index(False) :])
