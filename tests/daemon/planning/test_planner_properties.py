"""Property tests: after any sequence of map deltas, EDS and DSS equal the reference Dijkstra.

Random grids up to 64 x 64 and random deltas — cells blocked and freed at random, cells of
the current path blocked, the goal enclosed and released, walls that cut the map in two and
reopen — and after every delta: the EDS field and the DSS field (``update`` on each)
equal ``dijkstra.dijkstra_field`` cell for cell, and the path from the start is
``dijkstra.reference_path`` with cost g(start).
"""

from __future__ import annotations

import os

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from daemon.planning.dijkstra import dijkstra_field, reference_path
from daemon.planning.grid import INF, path_cost

PROPERTY = settings(
    # Bounded for CI; GUIDEBELT_HYPOTHESIS_EXAMPLES=2000 for a long soak.
    max_examples=int(os.environ.get("GUIDEBELT_HYPOTHESIS_EXAMPLES", "50")),
    deadline=None,
    suppress_health_check=[
        HealthCheck.too_slow,
        HealthCheck.data_too_large,
        HealthCheck.function_scoped_fixture,
    ],
)

DELTA_KINDS = ("random", "on_path", "around_goal", "wall", "reopen", "rect", "toggle_ends")


@st.composite
def worlds(draw):
    h, w = draw(st.integers(1, 64)), draw(st.integers(1, 64))
    density = draw(st.sampled_from([0.0, 0.1, 0.25, 0.4]))
    rng = np.random.default_rng(draw(st.integers(0, 2**32 - 1)))
    blocked = rng.random((h, w)) < density
    goal = (draw(st.integers(0, h - 1)), draw(st.integers(0, w - 1)))
    start = (draw(st.integers(0, h - 1)), draw(st.integers(0, w - 1)))
    if draw(st.booleans()):  # mostly the ends are free; sometimes they start blocked
        blocked[goal] = blocked[start] = False
    return blocked, goal, start


def draw_delta(data, truth, goal, start, walls) -> tuple[np.ndarray, np.ndarray]:
    """One map delta of a random kind: (flat cells, new blocked values), no repeated cell."""
    h, w = truth.shape
    kind = data.draw(st.sampled_from(DELTA_KINDS), label="kind")
    cells_of = lambda rows, cols: (np.asarray(rows) * w + np.asarray(cols)).ravel()  # noqa: E731
    if kind == "on_path":
        path = reference_path(dijkstra_field(truth, goal), truth, start)
        if len(path) > 0:
            pick = data.draw(st.lists(st.integers(0, len(path) - 1), min_size=1, max_size=3))
            cells = cells_of(path[pick, 0], path[pick, 1])
            return np.unique(cells), np.ones(np.unique(cells).size, bool)
        kind = "random"
    if kind == "around_goal":
        r = data.draw(st.integers(1, 2), label="ring")
        rr, cc = np.mgrid[goal[0] - r : goal[0] + r + 1, goal[1] - r : goal[1] + r + 1]
        ring = np.maximum(abs(rr - goal[0]), abs(cc - goal[1])) == r
        ring &= (rr >= 0) & (rr < h) & (cc >= 0) & (cc < w)
        cells = cells_of(rr[ring], cc[ring])
        return cells, np.full(cells.size, data.draw(st.booleans(), label="enclose"))
    if kind == "wall":
        vertical = data.draw(st.booleans(), label="vertical")
        at = data.draw(st.integers(0, (w if vertical else h) - 1), label="at")
        span = np.arange(h if vertical else w)
        cells = cells_of(span, at) if vertical else cells_of(at, span)
        if data.draw(st.booleans(), label="gap"):
            cells = np.delete(cells, data.draw(st.integers(0, cells.size - 1), label="gap_at"))
        walls.append(cells)
        return cells, np.ones(cells.size, bool)
    if kind == "reopen" and walls:
        cells = walls.pop(data.draw(st.integers(0, len(walls) - 1), label="which"))
        return cells, np.zeros(cells.size, bool)
    if kind == "rect":
        r0, c0 = data.draw(st.integers(0, h - 1)), data.draw(st.integers(0, w - 1))
        r1 = data.draw(st.integers(r0, min(h, r0 + 6) - 1))
        c1 = data.draw(st.integers(c0, min(w, c0 + 6) - 1))
        rr, cc = np.mgrid[r0 : r1 + 1, c0 : c1 + 1]
        cells = cells_of(rr, cc)
        return cells, np.full(cells.size, data.draw(st.booleans(), label="block"))
    if kind == "toggle_ends":
        end = data.draw(st.sampled_from([goal, start]), label="end")
        return cells_of(end[0], end[1]), np.array([not truth[end]])
    flat = data.draw(st.lists(st.integers(0, h * w - 1), min_size=1, max_size=12, unique=True))
    values = data.draw(st.lists(st.booleans(), min_size=len(flat), max_size=len(flat)))
    return np.array(flat, np.int64), np.array(values, bool)


def assert_matches_reference(planner, truth, goal, start, ref) -> None:
    np.testing.assert_array_equal(planner.blocked(), truth)
    np.testing.assert_array_equal(planner.costs(), ref)
    assert planner.cost_at(start) == int(ref[start])
    path = planner.path(start)
    np.testing.assert_array_equal(path, reference_path(ref, truth, start))
    if ref[start] < INF:
        assert tuple(path[0]) == start and tuple(path[-1]) == goal
        assert path_cost(path) == int(ref[start])
    else:
        assert path.shape == (0, 2)


@PROPERTY
@given(world=worlds(), data=st.data())
def test_eds_and_dss_equal_reference_after_every_delta(make, world, data):
    truth, goal, start = world
    eds, dss = make(), make("dss")
    eds.plan(truth, goal)
    dss.plan(truth, goal)
    ref = dijkstra_field(truth, goal)
    assert_matches_reference(eds, truth, goal, start, ref)
    assert_matches_reference(dss, truth, goal, start, ref)
    walls: list[np.ndarray] = []
    for _ in range(data.draw(st.integers(1, 8), label="n_deltas")):
        cells, values = draw_delta(data, truth, goal, start, walls)
        truth.reshape(-1)[cells] = values
        eds.update(cells, values)
        dss.update(cells, values)
        ref = dijkstra_field(truth, goal)
        assert_matches_reference(eds, truth, goal, start, ref)
        assert_matches_reference(dss, truth, goal, start, ref)


@pytest.mark.parametrize("seed", range(3))
def test_walk_eds_and_dss_take_the_same_cells(make, seed):
    """The closed loop in miniature: obstacles appear ahead of the walker on its path."""
    rng = np.random.default_rng(seed)
    truth = rng.random((48, 48)) < 0.2
    goal, here = (0, 24), (47, 24)
    truth[goal] = truth[here] = False
    eds, dss = make(), make("dss")
    eds.plan(truth, goal)
    dss.plan(truth, goal)
    steps = placed = 0
    while here != goal and steps < 500 and placed < 200:
        path = eds.path(here)
        np.testing.assert_array_equal(path, dss.path(here))
        if len(path) == 0:
            break
        if len(path) > 4 and rng.random() < 0.5:  # something appears three cells ahead
            cell = np.array([path[3][0] * 48 + path[3][1]])
            truth.reshape(-1)[cell] = True
            eds.update(cell, np.array([True]))
            dss.update(cell, np.array([True]))
            placed += 1
            continue
        here = (int(path[1][0]), int(path[1][1]))
        steps += 1
    np.testing.assert_array_equal(eds.costs(), dijkstra_field(truth, goal))
    assert here == goal or eds.cost_at(here) >= INF


@PROPERTY
@given(world=worlds(), data=st.data())
def test_the_path_read_in_a_step_is_the_reference_path_before_anything_settles(make, world, data):
    """The contract of a replanning step, read before any whole-field query: the path from the
    user (who walks along it between deltas) is ``reference_path`` of the current map, tie for
    tie, and its cost is the exact g of the user's cell. Then the whole field is exact too."""
    truth, goal, start = world
    eds = make()
    eds.plan(truth, goal)
    walls: list[np.ndarray] = []
    for _ in range(data.draw(st.integers(1, 8), label="n_deltas")):
        cells, values = draw_delta(data, truth, goal, start, walls)
        truth.reshape(-1)[cells] = values
        _, path = eds.update_and_path(cells, values, start)
        ref = dijkstra_field(truth, goal)
        np.testing.assert_array_equal(path, reference_path(ref, truth, start))
        if len(path) > 1:
            assert path_cost(path) == int(ref[start])
            ahead = data.draw(st.integers(0, len(path) - 1), label="walk")
            start = (int(path[ahead][0]), int(path[ahead][1]))
    np.testing.assert_array_equal(eds.costs(), dijkstra_field(truth, goal))
