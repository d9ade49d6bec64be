"""Edge cases and statistics, on every planner: defined results, never exceptions."""

from __future__ import annotations

import numpy as np
import pytest

from daemon.planning.dijkstra import dijkstra_field
from daemon.planning.grid import INF


def ring(blocked: np.ndarray, centre: tuple[int, int], r: int = 1) -> np.ndarray:
    """Block the square ring of radius r around centre."""
    rr, cc = centre
    blocked[rr - r : rr + r + 1, cc - r] = blocked[rr - r : rr + r + 1, cc + r] = True
    blocked[rr - r, cc - r : cc + r + 1] = blocked[rr + r, cc - r : cc + r + 1] = True
    return blocked


def test_unreachable_start(make):
    blocked = ring(np.zeros((20, 20), bool), (15, 10))
    p = make()
    p.plan(blocked, (2, 10))
    assert p.cost_at((15, 10)) == INF
    assert p.path((15, 10)).shape == (0, 2)
    assert p.cost_at((2, 12)) == 20


def test_enclosed_goal_then_released(make):
    goal = (10, 10)
    blocked = ring(np.zeros((21, 21), bool), goal, 2)
    p = make()
    p.plan(blocked, goal)
    g = p.costs()
    assert g[goal] == 0 and g[10, 11] == 10 and g[0, 0] == INF
    np.testing.assert_array_equal(p.path(goal), [goal])
    assert p.path((0, 0)).shape == (0, 2)
    gap = np.array([8 * 21 + 10])  # open the ring's top side
    p.update(gap, np.array([False]))
    blocked.reshape(-1)[gap] = False
    np.testing.assert_array_equal(p.costs(), dijkstra_field(blocked, goal))
    assert len(p.path((0, 0))) > 0


def test_goal_on_obstacle(make):
    blocked = np.zeros((12, 12), bool)
    blocked[3, 4] = True
    p = make()
    p.plan(blocked, (3, 4))
    assert (p.costs() == INF).all()
    assert p.path((10, 10)).shape == (0, 2) and p.path((3, 4)).shape == (0, 2)
    p.update(np.array([3 * 12 + 4]), np.array([False]))  # the obstacle moves away
    blocked[3, 4] = False
    np.testing.assert_array_equal(p.costs(), dijkstra_field(blocked, (3, 4)))
    p.update(np.array([3 * 12 + 4]), np.array([True]))  # and comes back
    assert (p.costs() == INF).all()


def test_start_on_obstacle(make):
    blocked = np.zeros((12, 12), bool)
    blocked[9, 9] = True
    p = make()
    p.plan(blocked, (0, 0))
    assert p.cost_at((9, 9)) == INF
    assert p.path((9, 9)).shape == (0, 2)


def test_single_cell_and_outside_cells(make):
    p = make()
    p.plan(np.zeros((1, 1), bool), (0, 0))
    np.testing.assert_array_equal(p.path((0, 0)), [[0, 0]])
    assert p.cost_at((0, 0)) == 0
    assert p.cost_at((1, 0)) == INF and p.cost_at((0, -1)) == INF
    assert p.path((5, 5)).shape == (0, 2)
    assert p.goal == (0, 0) and p.shape == (1, 1)


def test_goal_outside_the_map_is_a_clear_error(make):
    with pytest.raises(ValueError, match="outside"):
        make().plan(np.zeros((5, 5), bool), (5, 0))


def test_cell_outside_the_map_in_an_update_is_rejected_whole(make):
    p = make()
    p.plan(np.zeros((5, 5), bool), (0, 0))
    before = p.costs()
    with pytest.raises((IndexError, ValueError)):
        p.update(np.array([3, 25]), np.array([True, True]))
    np.testing.assert_array_equal(p.costs(), before)
    assert not p.blocked().any()


def test_copies_do_not_alias_the_planner(make):
    blocked = np.zeros((6, 6), bool)
    p = make()
    p.plan(blocked, (0, 0))
    blocked[1, 1] = True  # the caller's map is copied by plan
    p.costs()[:] = 0
    p.blocked()[:] = True
    np.testing.assert_array_equal(p.costs(), dijkstra_field(np.zeros((6, 6), bool), (0, 0)))


def test_an_empty_or_unchanging_delta_keeps_the_field(make):
    blocked = np.zeros((10, 10), bool)
    blocked[5, 2:8] = True
    p = make()
    p.plan(blocked, (0, 5))
    before = p.costs()
    p.update(np.empty(0, np.int64), np.empty(0, bool))
    p.update(np.array([5 * 10 + 3, 0]), np.array([True, False]))  # already so
    np.testing.assert_array_equal(p.costs(), before)


def test_stats_are_sane(make):
    """A small change far from the goal on a big open grid touches few cells."""
    n = 200
    blocked = np.zeros((n, n), bool)
    p = make()
    st = p.plan(blocked, (0, n // 2))
    assert st.iterations > 0 and st.cells_touched >= n * n // 2 and st.ms >= 0
    rr, cc = np.mgrid[150:153, 60:63]
    box = (rr * n + cc).ravel()
    behind = (n - 1, 61)  # the repair reaches the user's cell below the box
    st, _ = p.update_and_path(box, np.ones(box.size, bool), behind)
    # The cpu repair drops the cells behind the box as the change comes in (touched, not
    # expanded) and needs no expansion where the user's way around costs the same.
    assert (st.iterations > 0 or (p.backend, p.variant) == ("cpu", "fast")) and st.ms >= 0
    assert 0 < st.cells_touched < n * n // 10
    blocked.reshape(-1)[box] = True
    np.testing.assert_array_equal(p.costs(), dijkstra_field(blocked, (0, n // 2)))
    st, _ = p.update_and_path(box, np.zeros(box.size, bool), behind)
    assert st.iterations > 0 and 0 < st.cells_touched < n * n // 10
