"""GA with A* fitness (``cpu/genetic.py``, ``cpu/ga_astar.py``): paths, repeatability, bad input.

What is asserted, exactly:
- on random small maps (property tests), every answer of GA+A* and of the GA alone is either
  no path (empty, INF) — exactly when the goal cannot be reached, for GA+A* — or a walk from
  the start to the goal of 8-adjacent free cells, no cell twice, costing what ``cost_at``
  says and never less than the reference Dijkstra optimum. Diagonal steps between two blocked
  corners are allowed, as for A* and EDS (``grid.py``: inflation keeps the body clear);
- the same map, ends and ``GaParams`` give the same path, bit for bit;
- the kept path (the paper's Section 4.4) is given back while it is free, and the GA runs
  again from the user's cell once a cell of it is blocked; every answer after any delta is
  still a walkable path on the current map;
- bad input answers as ``astar`` and EDS do (``test_astar.py``, ``test_planner_edges.py``).
"""

from __future__ import annotations

import itertools
import os

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from daemon.planning import make_planner
from daemon.planning.cpu.ga_astar import GaAStarPlanner
from daemon.planning.cpu.genetic import GaParams, cut_loops, evolve, evolve_straight, straight_line
from daemon.planning.dijkstra import dijkstra_field
from daemon.planning.grid import INF, path_cost

PROPERTY = settings(
    max_examples=int(os.environ.get("GUIDEBELT_HYPOTHESIS_EXAMPLES", "40")),
    deadline=None,
    suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large],
)
SMALL = GaParams(population=6, generations=3, waypoints=2)


@st.composite
def maps(draw, max_side: int = 24):
    """A random map, goal and start; the ends are sometimes blocked."""
    h, w = draw(st.integers(1, max_side)), draw(st.integers(1, max_side))
    density = draw(st.sampled_from([0.0, 0.1, 0.25, 0.4]))
    rng = np.random.default_rng(draw(st.integers(0, 2**32 - 1)))
    blocked = rng.random((h, w)) < density
    goal = (draw(st.integers(0, h - 1)), draw(st.integers(0, w - 1)))
    start = (draw(st.integers(0, h - 1)), draw(st.integers(0, w - 1)))
    if draw(st.booleans()):
        blocked[goal] = blocked[start] = False
    return blocked, goal, start


def check_path(path: np.ndarray, truth: np.ndarray, start, goal, cost: int) -> None:
    """A well-formed answer: a walkable path of cost ``cost``, or empty with INF."""
    if cost >= INF:
        assert path.shape == (0, 2) and path.dtype == np.int32
        return
    assert path.dtype == np.int32 and path.ndim == 2 and path.shape[1] == 2
    assert tuple(path[0]) == tuple(start) and tuple(path[-1]) == tuple(goal)
    assert not truth[path[:, 0], path[:, 1]].any(), "the path enters a blocked cell"
    steps = np.abs(np.diff(path.astype(np.int64), axis=0))
    assert (steps.max(axis=1, initial=1) == 1).all(), "a step between non-neighbours"
    flat = path[:, 0].astype(np.int64) * truth.shape[1] + path[:, 1]
    assert np.unique(flat).size == flat.size, "a cell visited twice"
    assert path_cost(path) == cost


@PROPERTY
@given(world=maps(), seed=st.integers(0, 2**16))
def test_ga_astar_paths_are_walkable_and_no_cheaper_than_the_optimum(world, seed):
    truth, goal, start = world
    p = GaAStarPlanner(GaParams(population=6, generations=3, waypoints=2, seed=seed))
    p.plan(truth, goal)
    cost, path = p.cost_at(start), p.path(start)
    check_path(path, truth, start, goal, cost)
    optimum = int(dijkstra_field(truth, goal)[start])
    # No path exactly when none exists: waypoints come from the start's component.
    assert (cost >= INF) == (optimum >= INF)
    assert cost >= optimum


@PROPERTY
@given(world=maps(), seed=st.integers(0, 2**16))
def test_ga_alone_paths_are_straight_segments_through_free_cells(world, seed):
    truth, goal, start = world
    result = evolve_straight(truth, start, goal, GaParams(population=8, generations=4, seed=seed))
    check_path(result.path, truth, start, goal, result.cost)
    optimum = int(dijkstra_field(truth, goal)[start])
    assert result.cost >= optimum  # and may be INF where a path exists: no feasible chromosome
    if result.cost < INF and start != goal:
        # the path is the Bresenham lines through the waypoints (less any loop cut)
        points = [start, *map(tuple, result.waypoints), goal]
        lines = [
            straight_line(a, b)[1 if i else 0 :]
            for i, (a, b) in enumerate(itertools.pairwise(points))
        ]
        flat = np.concatenate(lines).astype(np.int64)
        expect = cut_loops(flat[:, 0] * truth.shape[1] + flat[:, 1])
        np.testing.assert_array_equal(path_flat(result.path, truth.shape[1]), expect)


def path_flat(path: np.ndarray, w: int) -> np.ndarray:
    return path[:, 0].astype(np.int64) * w + path[:, 1]


@PROPERTY
@given(world=maps(max_side=16), seed=st.integers(0, 2**16))
def test_a_seed_repeats_exactly(world, seed):
    truth, goal, start = world
    params = GaParams(population=6, generations=3, waypoints=3, seed=seed)
    a, b = evolve(truth, start, goal, params), evolve(truth, start, goal, params)
    np.testing.assert_array_equal(a.path, b.path)
    np.testing.assert_array_equal(a.waypoints, b.waypoints)
    assert (a.cost, a.fitness_cost, a.evaluations) == (b.cost, b.fitness_cost, b.evaluations)
    c, d = evolve_straight(truth, start, goal, params), evolve_straight(truth, start, goal, params)
    np.testing.assert_array_equal(c.path, d.path)
    p, q = GaAStarPlanner(params), GaAStarPlanner(params)
    for planner in (p, q):
        planner.plan(truth, goal)
    np.testing.assert_array_equal(p.path(start), q.path(start))


@PROPERTY
@given(world=maps(max_side=20), data=st.data())
def test_after_any_deltas_every_answer_is_walkable_on_the_current_map(world, data):
    truth, goal, start = world
    truth = truth.copy()
    p = GaAStarPlanner(SMALL)
    p.plan(truth, goal)
    h, w = truth.shape
    cell = start
    for _ in range(4):
        path = p.path(cell)
        check_path(path, truth, cell, goal, p.cost_at(cell))
        assert (len(path) == 0) == (dijkstra_field(truth, goal)[cell] >= INF)
        flat = data.draw(st.lists(st.integers(0, h * w - 1), max_size=6, unique=True))
        values = data.draw(st.lists(st.booleans(), min_size=len(flat), max_size=len(flat)))
        p.update(np.array(flat, np.int64), np.array(values, bool))
        truth.reshape(-1)[flat] = values
        if len(path) > 1 and not truth[tuple(path[1])]:
            cell = (int(path[1, 0]), int(path[1, 1]))  # the user takes one step


def test_the_kept_path_is_reused_until_a_cell_of_it_is_blocked():
    truth = np.zeros((30, 30), bool)
    truth[15, 3:27] = True
    base = truth.copy()
    p = GaAStarPlanner(GaParams(seed=3))
    p.plan(truth, (0, 15))
    first = p.path((29, 15))
    assert p.ga_runs == 1 and len(first) > 2
    np.testing.assert_array_equal(p.path(tuple(first[2])), first[2:])  # a step on: no GA run
    p.update(np.array([0]), np.array([True]))  # a change off the path keeps it
    np.testing.assert_array_equal(p.path(tuple(first[2])), first[2:])
    assert p.ga_runs == 1 and p.search_stats is not None and p.search_stats.iterations == 0
    mid = first[len(first) // 2]
    p.update(np.array([mid[0] * 30 + mid[1]]), np.array([True]))  # an obstacle on the path
    again = p.path(tuple(first[2]))
    assert p.ga_runs == 2 and not any((again == mid).all(axis=1))
    truth.reshape(-1)[[0, mid[0] * 30 + mid[1]]] = True
    check_path(again, truth, tuple(first[2]), (0, 15), path_cost(again))
    assert p.search_stats is not None and p.search_stats.iterations > 0
    # The reroute carries the old route over: never dearer (Eq. 2) than rejoining it.
    assert path_cost(again) <= path_cost(fresh_rejoin(truth, first, tuple(first[2]), p))
    twin = GaAStarPlanner(GaParams(seed=3))  # the same history gives the same answers
    twin.plan(base, (0, 15))
    twin.path((29, 15))
    twin.update(np.array([0, mid[0] * 30 + mid[1]]), np.array([True, True]))
    np.testing.assert_array_equal(twin.path(tuple(first[2])), again)
    off = p.path((29, 0))  # off the path: the GA from there
    assert p.ga_runs == 3 and tuple(off[0]) == (29, 0)


def fresh_rejoin(truth, route, start, p) -> np.ndarray:
    """A* from ``start`` to each carried waypoint of the old ``route`` and on to the goal."""
    from daemon.planning.cpu.genetic import Segments

    seg = Segments()
    seg.load(truth)
    ahead = route[int(np.argmax(-np.abs(route - np.asarray(start)).max(axis=1))) : -1]
    at = np.linspace(0, len(ahead) - 1, p.params.waypoints + 2)[1:-1].round().astype(int)
    points = [start, *[tuple(ahead[i]) for i in at], tuple(route[-1])]
    cells = [seg.path(seg.padded(a), seg.padded(b))[1 if i else 0 :]
             for i, (a, b) in enumerate(itertools.pairwise(points))]  # fmt: skip
    flat = np.concatenate(cells)
    return np.stack((flat // seg.width - 1, flat % seg.width - 1), axis=1)


def test_more_search_finds_paths_closer_to_the_optimum():
    rng = np.random.default_rng(5)
    truth = rng.random((40, 40)) < 0.25
    start, goal = (39, 2), (0, 37)
    truth[start] = truth[goal] = False
    optimum = int(dijkstra_field(truth, goal)[start])
    assert optimum < INF
    excess = {}
    for size in (2, 30):
        costs = [evolve(truth, start, goal, GaParams(population=size, generations=size,
                                                      seed=s)).cost for s in range(5)]  # fmt: skip
        excess[size] = np.median(costs) / optimum - 1
    assert excess[30] <= excess[2] and excess[30] < 0.1


def test_bad_input_answers_as_astar():
    truth = np.zeros((12, 12), bool)
    truth[3, 4] = True
    a, g = make_planner("astar", "cpu"), GaAStarPlanner()
    for p in (a, g):
        p.plan(truth, (3, 4))  # the goal in an obstacle
    for cell in [(10, 10), (3, 4), (-1, 0), (0, 12), (10**9, 3)]:
        assert g.cost_at(cell) == a.cost_at(cell) == INF
        assert g.path(cell).shape == (0, 2)
    g.update(np.array([3 * 12 + 4]), np.array([False]))  # the obstacle moves away
    assert len(g.path((10, 10))) > 0
    for p in (a, g):
        p.plan(truth, (0, 0))
    assert g.cost_at((3, 4)) == INF and g.path((3, 4)).shape == (0, 2)  # the start blocked
    ring = np.zeros((20, 20), bool)
    ring[14:17, [9, 11]] = ring[[14, 16], 9:12] = True
    g.plan(ring, (2, 10))
    assert g.cost_at((15, 10)) == INF and g.path((15, 10)).shape == (0, 2)  # cut off
    np.testing.assert_array_equal(g.path((2, 10)), [(2, 10)])  # the start is the goal
    assert g.cost_at((2, 10)) == 0
    for bad in (np.zeros((0, 0), bool), np.zeros((3,), bool)):
        with pytest.raises(ValueError):
            g.plan(bad, (0, 0))
    with pytest.raises(ValueError, match="outside"):
        g.plan(truth, (12, 0))
    with pytest.raises(IndexError):
        g.update(np.array([3, 400]), np.array([True, True]))  # the 20 x 20 map
    assert not g.blocked()[0, 3]  # rejected whole
    with pytest.raises(RuntimeError):
        GaAStarPlanner().update(np.array([0]), np.array([True]))
    assert GaAStarPlanner().path((0, 0)).shape == (0, 2)  # before plan: no path
    one = GaAStarPlanner()
    one.plan(np.zeros((1, 1), bool), (0, 0))
    np.testing.assert_array_equal(one.path((0, 0)), [(0, 0)])


def test_enclosed_goal_then_released():
    goal = (10, 10)
    truth = np.zeros((21, 21), bool)
    truth[8:13, [8, 12]] = truth[[8, 12], 8:13] = True
    g = GaAStarPlanner()
    g.plan(truth, goal)
    assert g.path((0, 0)).shape == (0, 2) and g.cost_at((0, 0)) == INF
    g.update(np.array([8 * 21 + 10]), np.array([False]))
    truth[8, 10] = False
    check_path(g.path((0, 0)), truth, (0, 0), goal, g.cost_at((0, 0)))


@pytest.mark.parametrize(
    "bad",
    [{"population": 1}, {"generations": 0}, {"waypoints": 0}, {"crossover_rate": 1.5},
     {"mutation_rate": -0.1}],
)  # fmt: skip
def test_bad_parameters_are_value_errors(bad):
    with pytest.raises(ValueError):
        GaParams(**bad)


@pytest.mark.parametrize("backend", ["cpu", "cuda", "reference", "auto"])
def test_the_registry_builds_it_on_the_cpu_for_every_backend(backend):
    p = make_planner("ga-astar", backend)
    assert isinstance(p, GaAStarPlanner) and p.backend == "cpu"
    assert p.params == GaParams() and p.name == "ga-astar-cpu-p8g6w2"
    with pytest.raises(ValueError):
        make_planner("ga-astar", "cpu", "nope")
