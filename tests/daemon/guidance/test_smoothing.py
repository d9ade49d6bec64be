"""Rubber-band smoothing never cuts a blocked cell; its metrics."""

from __future__ import annotations

import itertools

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from daemon.guidance.smoothing import (
    path_length,
    rubber_band,
    turning_angles,
    turning_histogram,
)
from daemon.guidance.turning_points import segment_free
from daemon.planning.dijkstra import dijkstra_field, reference_path
from daemon.planning.grid import INF


def random_case(seed: int, n: int = 32, density: float = 0.25):
    rng = np.random.default_rng(seed)
    blocked = rng.random((n, n)) < density
    blocked[0, :] = blocked[-1, :] = blocked[:, 0] = blocked[:, -1] = True
    start, goal = (n - 2, 1 + int(rng.integers(n - 2))), (1, 1 + int(rng.integers(n - 2)))
    blocked[start] = blocked[goal] = False
    g = dijkstra_field(blocked, goal)
    if g[start] >= INF:
        return None
    return blocked, reference_path(g, blocked, start)


def assert_never_cuts(blocked: np.ndarray, band: np.ndarray) -> None:
    cells = np.floor(band).astype(int)
    assert not blocked[cells[:, 0], cells[:, 1]].any()
    for a, b in itertools.pairwise(band):
        assert segment_free(blocked, a[0], a[1], b[0], b[1])
        # dense samples; 199 intervals never land exactly on the corner point a diagonal
        # between two cell centres touches (a point contact, which the planner allows)
        t = np.linspace(0, 1, 200)[:, None]
        pts = np.floor(a + t * (b - a)).astype(int)
        assert not blocked[pts[:, 0], pts[:, 1]].any()


@settings(max_examples=40, deadline=None)
@given(st.integers(0, 2**31 - 1), st.floats(0.0, 3.0), st.sampled_from([0.1, 0.05]))
def test_band_never_cuts_a_blocked_cell(seed: int, repulsion: float, cell_m: float) -> None:
    case = random_case(seed)
    if case is None:
        return
    blocked, path = case
    band = rubber_band(path, blocked, repulsion=repulsion, cell_m=cell_m, iterations=60)
    assert np.allclose(band[0], path[0] + 0.5) and np.allclose(band[-1], path[-1] + 0.5)
    assert_never_cuts(blocked, band)


def test_band_shortens_and_straightens_a_grid_path() -> None:
    blocked = np.zeros((60, 60), dtype=bool)
    blocked[20:25, 10:50] = True
    g = dijkstra_field(blocked, (2, 30))
    path = reference_path(g, blocked, (55, 30))
    raw = path + 0.5
    band = rubber_band(path, blocked)
    assert path_length(band) < path_length(raw)
    assert_never_cuts(blocked, band)
    # the grid path turns only by 45° multiples; the band spreads them into small bends
    assert set(np.round(turning_angles(raw)).astype(int)) <= {0, 45, 90, 135}
    assert np.median(turning_angles(band)[turning_angles(band) > 0.5]) < 20


def test_metrics() -> None:
    square = np.array([[0, 0], [0, 3], [4, 3]], dtype=float)
    assert path_length(square) == 7.0
    assert np.isclose(path_length(square, cell_m=0.1), 0.7)
    assert np.allclose(turning_angles(square), [90.0])
    hist = turning_histogram(square)
    assert hist.sum() == 1 and hist[np.searchsorted(np.arange(0, 95, 5), 90, side="right") - 1]
    assert turning_angles(np.array([[0, 0], [1, 1]], dtype=float)).size == 0
    assert turning_angles(np.array([[0, 0], [1, 1], [1, 1], [2, 2]], dtype=float)).tolist() == [0]
