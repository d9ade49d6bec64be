"""The reference Dijkstra itself, against closed forms and an independent fixed point."""

from __future__ import annotations

import itertools

import numpy as np
import pytest

from daemon.planning.dijkstra import dijkstra_field, reference_path, reference_pred
from daemon.planning.grid import INF, NEIGHBOUR_COST, NEIGHBOUR_DC, NEIGHBOUR_DR, path_cost


def bellman_fixed_point(blocked: np.ndarray, goal: tuple[int, int]) -> np.ndarray:
    """Synchronous Bellman-Ford sweeps until nothing changes: slow, independent, exact."""
    h, w = blocked.shape
    g = np.full((h + 2, w + 2), int(INF), np.int64)
    if blocked[goal]:
        return g[1:-1, 1:-1].astype(np.int32)
    g[goal[0] + 1, goal[1] + 1] = 0
    free = np.pad(~blocked, 1)
    while True:
        new = g.copy()
        for dr, dc, cost in zip(NEIGHBOUR_DR, NEIGHBOUR_DC, NEIGHBOUR_COST, strict=True):
            shifted = np.roll(g, (-int(dr), -int(dc)), axis=(0, 1)) + int(cost)
            new = np.minimum(new, np.where(free, shifted, int(INF)))
        new = np.minimum(new, int(INF))
        if np.array_equal(new, g):
            return g[1:-1, 1:-1].astype(np.int32)
        g = new


def test_open_grid_is_the_octile_distance():
    g = dijkstra_field(np.zeros((30, 40), bool), (7, 11))
    rr, cc = np.mgrid[0:30, 0:40]
    dy, dx = abs(rr - 7), abs(cc - 11)
    np.testing.assert_array_equal(g, 14 * np.minimum(dy, dx) + 10 * abs(dy - dx))


@pytest.mark.parametrize("seed", range(10))
def test_random_grids_match_an_independent_fixed_point(seed):
    rng = np.random.default_rng(seed)
    blocked = rng.random((25, 31)) < 0.3
    goal = (int(rng.integers(25)), int(rng.integers(31)))
    blocked[goal] = seed % 5 == 0  # sometimes the goal itself is blocked
    g = dijkstra_field(blocked, goal)
    np.testing.assert_array_equal(g, bellman_fixed_point(blocked, goal))
    assert (g[blocked] == INF).all()


def test_a_wall_cuts_the_map_and_paths_follow_the_field():
    blocked = np.zeros((10, 10), bool)
    blocked[5, :] = True
    g = dijkstra_field(blocked, (0, 0))
    assert (g[6:] == INF).all() and (g[:5] < INF).all()
    blocked[5, 9] = False
    g = dijkstra_field(blocked, (0, 0))
    path = reference_path(g, blocked, (9, 0))
    assert tuple(path[0]) == (9, 0) and tuple(path[-1]) == (0, 0)
    assert path_cost(path) == g[9, 0]
    assert tuple(path[len(path) // 2]) != (5, 0) and [5, 9] in path.tolist()


def test_pred_map_points_along_the_path():
    rng = np.random.default_rng(3)
    blocked = rng.random((20, 20)) < 0.2
    blocked[0, 0] = blocked[19, 19] = False
    g = dijkstra_field(blocked, (0, 0))
    pred = reference_pred(g, blocked)
    path = reference_path(g, blocked, (19, 19))
    for (r, c), (nr, nc) in itertools.pairwise(path):
        k = pred[r, c]
        assert (r + NEIGHBOUR_DR[k], c + NEIGHBOUR_DC[k]) == (nr, nc)
    assert pred[0, 0] == -1 and (pred[blocked] == -1).all()
