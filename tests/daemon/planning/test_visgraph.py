"""The visibility-graph planner (``daemon/planning/visgraph``): polygons, paths, bad input.

What is asserted, exactly:
- the pieces are convex, have fewer than seven edges, hold every blocked cell's whole square
  strictly inside one of them and cover no free cell's centre;
- the A* path's length equals the shortest path over the same polygons found by brute force:
  Dijkstra over every pair of feature points, each pair judged by a separating-axis test
  written here (not the planner's eq. (4)/(5) clipping);
- the path's segments enter no polygon, and its cells are free 8-neighbours from start to goal;
- bad input answers exactly as EDS does (empty path, INF), and a start or goal change or a map
  update gives what a fresh planner gives.
"""

from __future__ import annotations

import heapq
import itertools
import os

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from daemon.planning import make_planner
from daemon.planning.grid import INF, path_cost
from daemon.planning.visgraph.planner import VisGraphPlanner
from daemon.planning.visgraph.polygons import MAX_EDGES
from daemon.planning.visgraph.raster import rasterise

PROPERTY = settings(
    max_examples=int(os.environ.get("GUIDEBELT_HYPOTHESIS_EXAMPLES", "40")),
    deadline=None,
    suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large],
)


@st.composite
def maps(draw, max_side: int = 16):
    """A small map of rectangles, discs or noise, with free start and goal cells."""
    h, w = draw(st.integers(2, max_side)), draw(st.integers(2, max_side))
    rng = np.random.default_rng(draw(st.integers(0, 2**32 - 1)))
    kind = draw(st.sampled_from(["rects", "discs", "noise"]))
    blocked = np.zeros((h, w), dtype=bool)
    if kind == "noise":
        blocked = rng.random((h, w)) < draw(st.sampled_from([0.05, 0.15, 0.3]))
    else:
        rr, cc = np.mgrid[0:h, 0:w]
        for _ in range(int(rng.integers(1, 7))):
            r, c = int(rng.integers(0, h)), int(rng.integers(0, w))
            if kind == "rects":
                blocked[r : r + int(rng.integers(1, 6)), c : c + int(rng.integers(1, 6))] = True
            else:
                blocked |= (rr - r) ** 2 + (cc - c) ** 2 <= int(rng.integers(1, 10))
    free = np.argwhere(~blocked)
    if len(free) < 2:
        blocked[0, 0] = blocked[h - 1, w - 1] = False
        free = np.argwhere(~blocked)
    if draw(st.booleans()):  # ends on opposite sides, so the path must bend round things
        quarter = max(1, len(free) // 4)
        i = draw(st.integers(0, quarter - 1))
        j = draw(st.integers(len(free) - quarter, len(free) - 1))
    else:
        i, j = draw(st.integers(0, len(free) - 1)), draw(st.integers(0, len(free) - 1))
    return blocked, tuple(int(x) for x in free[i]), tuple(int(x) for x in free[j])


# -- an independent geometry: separating axes ------------------------------------------------


def enters(poly: np.ndarray, a: np.ndarray, b: np.ndarray) -> bool:
    """Does segment ab meet the open convex polygon? Separating axes: the edges' normals and
    the segment's normal; touching projections separate (no interior is shared)."""
    axes = [np.array([e[1], -e[0]]) for e in np.roll(poly, -1, axis=0) - poly]
    d = b - a
    axes.append(np.array([d[1], -d[0]]))
    for axis in axes:
        norm = np.hypot(*axis)
        if norm < 1e-12:
            continue
        pp = poly @ axis / norm
        sp = np.array([a @ axis, b @ axis]) / norm
        if sp.max() <= pp.min() + 1e-7 or sp.min() >= pp.max() - 1e-7:
            return False
    return True


def strictly_inside(poly: np.ndarray, p: np.ndarray) -> bool:
    edges = np.roll(poly, -1, axis=0) - poly
    rel = p - poly
    return bool(np.all(edges[:, 0] * rel[:, 1] - edges[:, 1] * rel[:, 0] > 1e-7))


def brute_force_length(pieces, shape, start, goal) -> float:
    """Dijkstra over every pair of points of the same polygons, O(n^2) pairs x polygons."""
    h, w = shape
    points = [np.array(start, float), np.array(goal, float)]
    for i, poly in enumerate(pieces):
        for v in poly:
            in_map = -0.5 <= v[0] <= h - 0.5 and -0.5 <= v[1] <= w - 0.5
            others = (q for j, q in enumerate(pieces) if j != i)
            if in_map and not any(strictly_inside(q, v) for q in others):
                points.append(v)
    n = len(points)
    dist = [np.inf] * n
    dist[0] = 0.0
    heap = [(0.0, 0)]
    done = [False] * n
    while heap:
        d, u = heapq.heappop(heap)
        if done[u]:
            continue
        done[u] = True
        if u == 1:
            return d
        for v in range(n):
            if done[v]:
                continue
            nd = d + float(np.hypot(*(points[v] - points[u])))
            if nd < dist[v] and not any(enters(p, points[u], points[v]) for p in pieces):
                dist[v] = nd
                heapq.heappush(heap, (nd, v))
    return np.inf


def check_cells(path: np.ndarray, blocked: np.ndarray, start, goal) -> None:
    assert path.dtype == np.int32 and path.ndim == 2 and path.shape[1] == 2
    assert tuple(path[0]) == tuple(start) and tuple(path[-1]) == tuple(goal)
    assert not blocked[path[:, 0], path[:, 1]].any(), "the path enters a blocked cell"
    steps = np.abs(np.diff(path.astype(np.int64), axis=0))
    assert (steps.max(axis=1, initial=1) == 1).all(), "a step between non-neighbours"


# -- properties ----------------------------------------------------------------------------


@pytest.mark.timeout(60)
@PROPERTY
@given(world=maps())
def test_pieces_are_convex_small_and_cover_every_blocked_square_and_no_free_centre(world):
    blocked, _, goal = world
    p = VisGraphPlanner()
    p.plan(blocked, goal)
    pieces = p.pieces()
    for poly in pieces:
        assert 3 <= len(poly) <= MAX_EDGES
        edges = np.roll(poly, -1, axis=0) - poly
        turns = (
            edges[:, 0] * np.roll(edges, -1, axis=0)[:, 1]
            - edges[:, 1] * np.roll(edges, -1, axis=0)[:, 0]
        )
        assert (turns > 0).all(), "not strictly convex counter-clockwise"
        for r, c in itertools.product(range(blocked.shape[0]), range(blocked.shape[1])):
            if not blocked[r, c]:
                edges_rel = np.array([r, c]) - poly
                inside = edges[:, 0] * edges_rel[:, 1] - edges[:, 1] * edges_rel[:, 0] >= -1e-7
                assert not inside.all(), f"free centre {(r, c)} under a polygon"
    for r, c in np.argwhere(blocked):
        corners = [np.array([r + dr, c + dc], float) for dr in (-0.5, 0.5) for dc in (-0.5, 0.5)]
        assert any(all(strictly_inside(q, x) for x in corners) for q in pieces), (r, c)


@pytest.mark.timeout(120)
@PROPERTY
@given(world=maps())
def test_length_equals_a_brute_force_shortest_path_and_the_path_stays_clear(world):
    blocked, start, goal = world
    p = VisGraphPlanner(fallback=False)
    p.plan(blocked, goal)
    pieces = p.pieces()
    want = brute_force_length(pieces, blocked.shape, start, goal)
    path = p.path(start)
    if not np.isfinite(want):
        assert path.shape == (0, 2) and p.cost_at(start) == INF
        return
    assert p.last_length == pytest.approx(want, abs=1e-6)
    check_cells(path, blocked, start, goal)
    assert p.cost_at(start) == path_cost(path)
    points, length, _ = p.polygon_path(start)
    assert length == pytest.approx(want, abs=1e-6)
    for a, b in itertools.pairwise(points):
        assert not any(enters(q, a, b) for q in pieces), "a segment enters a polygon"
    np.testing.assert_array_equal(rasterise(points), path)


@pytest.mark.timeout(60)
@PROPERTY
@given(world=maps(), again=st.data())
def test_a_new_start_or_a_map_update_gives_what_a_fresh_planner_gives(world, again):
    blocked, start, goal = world
    p = VisGraphPlanner(fallback=False)
    p.plan(blocked, goal)
    p.path(start)
    nodes = p.nodes
    free = np.argwhere(~blocked)
    other = tuple(int(x) for x in free[again.draw(st.integers(0, len(free) - 1))])
    fresh = VisGraphPlanner(fallback=False)
    fresh.plan(blocked, goal)
    assert p.cost_at(other) == fresh.cost_at(other)
    np.testing.assert_array_equal(p.nodes, nodes)  # the start moved; nothing was rebuilt
    h, w = blocked.shape
    cells = np.array(again.draw(st.lists(st.integers(0, h * w - 1), min_size=1, max_size=6)))
    values = np.array(again.draw(st.lists(st.booleans(), min_size=len(cells), max_size=len(cells))))
    p.update(cells, values)
    truth = blocked.copy().reshape(-1)
    truth[cells] = values
    fresh.plan(truth.reshape(h, w), goal)
    for cell in (start, other):
        assert p.cost_at(cell) == fresh.cost_at(cell)
        assert p.last_length == fresh.last_length or p.last_length == pytest.approx(
            fresh.last_length
        )


# -- examples ------------------------------------------------------------------------------


def test_around_a_wall_the_path_is_the_taut_string():
    blocked = np.zeros((30, 30), bool)
    blocked[10:20, 5:25] = True
    p = VisGraphPlanner()
    p.plan(blocked, (2, 15))
    points, length, _ = p.polygon_path((28, 15))
    # Around the wall's east end: two corners, each pushed out by the offset.
    corner_a, corner_b = np.array([19.5, 24.5]), np.array([9.5, 24.5])
    taut = np.hypot(*(corner_a - (28, 15))) + 10 + np.hypot(*((2, 15) - corner_b))
    assert taut < length < taut + 0.2
    assert len(points) == 4
    check_cells(p.path((28, 15)), blocked, (28, 15), (2, 15))


def test_a_new_goal_on_the_same_map_keeps_the_graph():
    blocked = np.zeros((30, 30), bool)
    blocked[10:20, 5:25] = True
    p = VisGraphPlanner()
    p.plan(blocked, (2, 15))
    first = p.cost_at((28, 15))
    judged = p._vis.copy()
    assert p.plan(blocked, (28, 15)).iterations == 0  # nothing cut again
    assert (p._vis[:-2, :-2] == judged[:-2, :-2]).all()  # the points' judgements stand
    assert p.cost_at((2, 15)) == first and p.goal == (28, 15)
    fresh = VisGraphPlanner()
    fresh.plan(blocked, (28, 15))
    assert fresh.cost_at((2, 15)) == first


def test_the_whole_graph_and_dijkstra_find_the_same_length_as_lazy_a_star():
    blocked = np.zeros((40, 40), bool)
    for r, c in [(8, 8), (20, 25), (30, 10), (12, 30)]:
        blocked[r : r + 5, c : c + 4] = True
    lengths = []
    for heuristic, whole in [(True, False), (False, False), (False, True)]:
        p = VisGraphPlanner(heuristic=heuristic)
        p.plan(blocked, (1, 38))
        lengths.append(p.polygon_path((38, 1), whole_graph=whole)[1])
    assert lengths[0] == pytest.approx(lengths[1]) and lengths[0] == pytest.approx(lengths[2])


def test_changing_one_cell_cuts_one_block_again():
    blocked = np.zeros((64, 64), bool)
    blocked[20:40, 10:50] = True
    p = VisGraphPlanner()
    p.plan(blocked, (2, 30))
    assert p.polygons.cut > 1
    stats = p.update(np.array([5 * 64 + 5]), np.array([True]))
    assert stats.iterations == 1 == p.polygons.cut and stats.cells_touched == 1
    assert p.update(np.array([5 * 64 + 5]), np.array([True])).iterations == 0  # no change


def test_a_diagonal_gap_is_shut_by_the_polygons_and_the_grid_path_is_the_fallback():
    blocked = np.zeros((9, 9), bool)
    blocked[3:5, :] = True
    blocked[3, 5] = blocked[4, 4] = False  # the only way through: corner to corner
    start, goal = (8, 4), (0, 4)
    strict = VisGraphPlanner(fallback=False)
    strict.plan(blocked, goal)
    assert strict.path(start).shape == (0, 2) and strict.cost_at(start) == INF
    eds = make_planner("eds", "cpu")
    eds.plan(blocked, goal)
    assert eds.cost_at(start) < INF
    p = VisGraphPlanner()
    p.plan(blocked, goal)
    path = p.path(start)
    check_cells(path, blocked, start, goal)
    assert p.fallbacks == 1 and p.last_fell_back and p.cost_at(start) == eds.cost_at(start)


# -- bad input, as EDS answers it --------------------------------------------------------------


def both(blocked, goal):
    v, e = VisGraphPlanner(), make_planner("eds", "cpu")
    v.plan(blocked, goal)
    e.plan(blocked, goal)
    return v, e


def test_goal_in_an_obstacle_start_blocked_outside_or_cut_off_answer_as_eds():
    blocked = np.zeros((20, 20), bool)
    blocked[14:17, 9:12] = True
    blocked[15, 10] = False  # a free cell walled in
    blocked[2, 2] = True
    v, e = both(blocked, (2, 10))
    for cell in [(2, 2), (-1, 0), (0, -1), (20, 0), (0, 20), (15, 10), (10**9, 3)]:
        assert v.cost_at(cell) == e.cost_at(cell) == INF
        assert v.path(cell).shape == (0, 2) and v.path(cell).dtype == np.int32
    np.testing.assert_array_equal(v.path((2, 10)), [(2, 10)])  # the start is the goal
    assert v.cost_at((2, 10)) == 0 and v.cost_at((2, 12)) == e.cost_at((2, 12)) == 20
    v, e = both(blocked, (2, 2))  # goal in an obstacle
    for cell in [(10, 10), (2, 2), (2, 3)]:
        assert v.cost_at(cell) == e.cost_at(cell) == INF and v.path(cell).shape == (0, 2)


def test_an_empty_map_is_a_straight_line_and_a_full_one_has_no_path():
    v = VisGraphPlanner()
    v.plan(np.zeros((10, 30), bool), (0, 29))
    assert v.nodes.shape == (0, 2) and v.last_length == np.inf
    path = v.path((9, 0))
    check_cells(path, np.zeros((10, 30), bool), (9, 0), (0, 29))
    assert v.last_length == pytest.approx(np.hypot(9, 29))
    full = np.ones((5, 5), bool)
    v.plan(full, (0, 0))
    assert v.cost_at((4, 4)) == INF and v.path((4, 4)).shape == (0, 2)
    with pytest.raises(ValueError):
        v.plan(np.zeros((0, 4), bool), (0, 0))
    with pytest.raises(ValueError):
        v.plan(np.zeros((4, 4), bool), (4, 0))


def test_update_outside_the_map_is_rejected_whole_and_update_before_plan_is_an_error():
    v = VisGraphPlanner()
    with pytest.raises(RuntimeError):
        v.update(np.array([0]), np.array([True]))
    assert v.cost_at((0, 0)) == INF and v.path((0, 0)).shape == (0, 2)
    v.plan(np.zeros((8, 8), bool), (0, 0))
    for bad in ([3, 64], [-1, 3]):
        with pytest.raises(IndexError):
            v.update(np.array(bad), np.array([True, True]))
        assert not v.blocked().any()
    assert v.cost_at((7, 7)) == 7 * 14


@pytest.mark.parametrize("backend", ["cpu", "cuda", "auto", "reference"])
def test_the_registry_builds_it_on_the_cpu_for_every_backend(backend):
    p = make_planner("visgraph", backend)
    assert isinstance(p, VisGraphPlanner) and p.backend == "cpu" and p.name == "visgraph-cpu"
    assert p.fallback and p.use_h
    with pytest.raises(ValueError, match="variant"):
        make_planner("visgraph", backend, "turbo")


def test_more_than_four_feature_points_of_one_hexagon_can_be_visible():
    """§4.2 says at most four feature points of a polygon with fewer than seven edges are
    points of visibility for a point; a flat hexagon seen along its axis shows all six."""
    from daemon.planning.visgraph.graph import conflicts

    angles = np.radians([90, 54, 18, -18, -54, -90])  # a half disc's arc and its chord
    hexagon = np.stack([np.cos(angles), np.sin(angles)], axis=1)[::-1].copy()
    assert strictly_inside(hexagon, np.array([0.5, 0.0]))  # counter-clockwise, as the planner's

    def visible_from(m) -> int:
        xs, ys = hexagon[:, 0].copy(), hexagon[:, 1].copy()
        return sum(not conflicts(xs, ys, 6, m[0], m[1], v[0], v[1]) for v in hexagon)

    assert visible_from((100.0, 0.0)) == 6
    assert visible_from((-100.0, 0.0)) == 2  # behind the chord: its two ends only
