"""Extended A* (``cpu/extended_astar.py``, Rettkowski et al. 2016): what holds and what does not.

What is asserted, exactly:
- every answer is well formed: a path from the start to the goal through free cells, steps
  between 8-neighbours, costing what ``cost_at`` says; or empty with INF;
- its cost is >= the Dijkstra optimum; no path whenever Dijkstra has none; with
  ``clearance = 0`` a path whenever Dijkstra has one;
- every cell of the path but the start and the goal has no blocked cell within ``clearance``;
- with open neighbours re-evaluated (``skip_open=False``) the cost is the optimum of the map
  where the cells within ``clearance`` of an obstacle are blocked too (start and goal not):
  the memory criterion alone only shrinks the graph, and the goal test on generation costs
  nothing with the octile heuristic;
- skipping open neighbours does break optimality (a 4 x 3 map where it does), and the memory
  criterion does make a reachable goal unreachable (a one-cell corridor);
- with the fallback (what the registry builds) a path is found exactly when Dijkstra has one,
  well formed, and the work of both searches is counted.
"""

from __future__ import annotations

import os

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from daemon.planning import make_planner
from daemon.planning.cpu.astar import AStarPlanner
from daemon.planning.cpu.extended_astar import DEFAULT_CLEARANCE, ExtendedAStarPlanner
from daemon.planning.dijkstra import dijkstra_field
from daemon.planning.grid import INF, path_cost

PROPERTY = settings(
    max_examples=int(os.environ.get("GUIDEBELT_HYPOTHESIS_EXAMPLES", "50")),
    deadline=None,
    suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large],
)


@st.composite
def maps(draw, max_side: int = 30):
    """A random map, goal and start; the ends are sometimes blocked."""
    h, w = draw(st.integers(1, max_side)), draw(st.integers(1, max_side))
    density = draw(st.sampled_from([0.0, 0.05, 0.1, 0.25, 0.4]))
    rng = np.random.default_rng(draw(st.integers(0, 2**32 - 1)))
    blocked = rng.random((h, w)) < density
    goal = (draw(st.integers(0, h - 1)), draw(st.integers(0, w - 1)))
    start = (draw(st.integers(0, h - 1)), draw(st.integers(0, w - 1)))
    if draw(st.booleans()):
        blocked[goal] = blocked[start] = False
    return blocked, goal, start


def dilate(blocked: np.ndarray, d: int) -> np.ndarray:
    """Cells with a blocked cell within ``d`` (Chebyshev), computed the slow, obvious way."""
    h, w = blocked.shape
    out = blocked.copy()
    for r, c in zip(*np.nonzero(blocked), strict=True):
        out[max(0, r - d) : r + d + 1, max(0, c - d) : c + d + 1] = True
    return out[:h, :w]


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
    assert len(np.unique(path, axis=0)) == len(path), "the path visits a cell twice"
    assert path_cost(path) == cost


@PROPERTY
@given(world=maps(), d=st.integers(0, 3), skip_open=st.booleans(), on_gen=st.booleans())
def test_every_path_is_feasible_and_no_cheaper_than_the_optimum(world, d, skip_open, on_gen):
    truth, goal, start = world
    p = ExtendedAStarPlanner(clearance=d, skip_open=skip_open, goal_on_generation=on_gen)
    p.plan(truth, goal)
    optimum = int(dijkstra_field(truth, goal)[start])
    cost = p.cost_at(start)
    check_path(p.path(start), truth, start, goal, cost)
    assert cost >= optimum
    if optimum >= INF:
        assert cost >= INF  # no path where none exists
    if d == 0:
        assert (cost < INF) == (optimum < INF)  # without the criterion it never misses one
    if cost < INF and len(p.path(start)) > 2:
        inner = p.path(start)[1:-1]
        near = dilate(truth, d)
        assert not near[inner[:, 0], inner[:, 1]].any(), "a cell within d of an obstacle"
    stats = p.search_stats
    if not (truth[start] or truth[goal]):
        assert stats is not None and 1 <= stats.iterations <= truth.size
        assert 1 <= p.max_open <= stats.cells_touched <= truth.size


@PROPERTY
@given(world=maps(), d=st.integers(0, 3), on_gen=st.booleans())
def test_without_skipping_the_cost_is_the_optimum_of_the_shrunk_map(world, d, on_gen):
    truth, goal, start = world
    if truth[goal] or truth[start]:
        return
    p = ExtendedAStarPlanner(clearance=d, skip_open=False, goal_on_generation=on_gen)
    p.plan(truth, goal)
    shrunk = dilate(truth, d)
    shrunk[start] = shrunk[goal] = False
    assert p.cost_at(start) == int(dijkstra_field(shrunk, goal)[start])


def test_skipping_open_neighbours_breaks_optimality():
    """Found by a seeded search over small maps: the first way into (1, 0) comes from (2, 1)
    and is kept, the cheaper one is never looked at."""
    truth = np.array([[0, 0, 0], [0, 1, 0], [0, 0, 0], [0, 0, 0]], bool)
    goal, start = (0, 1), (3, 2)
    assert int(dijkstra_field(truth, goal)[start]) == 34
    p = ExtendedAStarPlanner(clearance=0)
    p.plan(truth, goal)
    assert p.cost_at(start) == 42
    check_path(p.path(start), truth, start, goal, 42)
    q = ExtendedAStarPlanner(clearance=0, skip_open=False)
    q.plan(truth, goal)
    assert q.cost_at(start) == 34


def test_the_memory_criterion_closes_a_narrow_corridor():
    truth = np.ones((7, 20), bool)
    truth[3, :] = False  # one free row between walls
    goal, start = (3, 19), (3, 0)
    for d, expected in [(0, 190), (1, INF), (2, INF)]:
        p = ExtendedAStarPlanner(clearance=d)
        p.plan(truth, goal)
        assert p.cost_at(start) == expected
        assert (len(p.path(start)) == 20) == (expected < INF)
    truth[2:5, :] = False  # three free rows: d = 1 passes along the middle one
    p = ExtendedAStarPlanner(clearance=1)
    p.plan(truth, goal)
    path = p.path(start)
    assert p.cost_at(start) == 190 and (path[1:-1, 0] == 3).all()


def test_the_goal_and_the_start_are_exempt_and_the_map_edge_is_no_wall():
    truth = np.zeros((9, 9), bool)
    truth[0, 3] = truth[0, 5] = True  # the goal (0, 4) between two obstacles
    p = ExtendedAStarPlanner(clearance=1)
    p.plan(truth, (0, 4))
    assert p.cost_at((1, 4)) == 10  # start and goal both within 1 of an obstacle
    # Every neighbour of the goal is within 1 of an obstacle: reachable, yet no path.
    assert int(dijkstra_field(truth, (0, 4))[8, 4]) == 80 and p.cost_at((8, 4)) == INF
    p.plan(np.zeros((5, 5), bool), (0, 0))  # along the map's edge: no obstacle there
    assert p.cost_at((4, 4)) == 56 and p.cost_at((0, 4)) == 40


def test_on_an_empty_map_it_expands_no_more_than_astar():
    a, e = AStarPlanner(), ExtendedAStarPlanner()
    for p in (a, e):
        p.plan(np.zeros((120, 160), bool), (5, 150))
    assert a.cost_at((115, 5)) == e.cost_at((115, 5)) == 1890
    sa, se = a.search_stats, e.search_stats
    assert sa is not None and se is not None
    assert se.iterations == sa.iterations - 1  # the goal is not popped
    assert e.max_open <= a.max_open
    stats, path = e.update_and_path(np.array([], np.int64), np.array([], bool), (115, 6))
    assert stats.iterations >= 1 and stats.cells_touched >= stats.iterations and len(path) > 0


def test_skipping_open_neighbours_can_expand_more_than_it_saves():
    """With the octile heuristic a cell kept at its first, dearer g has a larger f, so the
    search fans out behind an obstacle: measured, not assumed (see the notes)."""
    truth = np.zeros((120, 160), bool)
    truth[40:80, 60:64] = True
    a, e, keep = AStarPlanner(), ExtendedAStarPlanner(), ExtendedAStarPlanner(skip_open=False)
    for p in (a, e, keep):
        p.plan(truth, (5, 150))
    assert a.cost_at((115, 5)) == keep.cost_at((115, 5)) == 1890 < e.cost_at((115, 5))
    sa, se, sk = a.search_stats, e.search_stats, keep.search_stats
    assert sa is not None and se is not None and sk is not None
    assert se.iterations > 2 * sa.iterations and sk.iterations <= sa.iterations


def test_bad_input_answers_as_astar():
    truth = np.zeros((12, 12), bool)
    truth[3, 4] = True
    a, e = AStarPlanner(), ExtendedAStarPlanner()
    for p in (a, e):
        p.plan(truth, (3, 4))  # the goal in an obstacle
    for cell in [(10, 10), (3, 4), (-1, 0), (0, 12), (10**9, 3)]:
        assert e.cost_at(cell) == a.cost_at(cell) == INF
        assert e.path(cell).shape == (0, 2)
    for p in (a, e):
        p.plan(truth, (0, 0))
    assert e.cost_at((3, 4)) == INF and e.path((3, 4)).shape == (0, 2)  # the start blocked
    for bad in (np.zeros((0, 0), bool), np.zeros((3,), bool)):
        for p in (a, e):
            with pytest.raises(ValueError):
                p.plan(bad, (0, 0))
    with pytest.raises(ValueError):
        e.plan(truth, (12, 0))
    with pytest.raises(RuntimeError):
        ExtendedAStarPlanner().update(np.array([0]), np.array([True]))
    for bad_d in (-1, 1.5):
        with pytest.raises(ValueError):
            ExtendedAStarPlanner(clearance=bad_d)  # type: ignore[arg-type]


@PROPERTY
@given(world=maps(), d=st.integers(1, 3))
def test_with_the_fallback_a_path_is_found_exactly_when_one_exists(world, d):
    truth, goal, start = world
    p = ExtendedAStarPlanner(clearance=d, fallback=True)
    paper = ExtendedAStarPlanner(clearance=d)
    p.plan(truth, goal)
    paper.plan(truth, goal)
    path, cost = p.path(start), p.cost_at(start)
    check_path(path, truth, start, goal, cost)
    optimum = dijkstra_field(truth, goal)[start]
    assert (cost < INF) == (optimum < INF)
    assert cost >= optimum
    # It searches again exactly when the paper's form misses with both ends free.
    ends_free = not truth[start] and not truth[goal]
    assert p.fallbacks == int(ends_free and paper.cost_at(start) >= INF)


def test_the_fallback_finds_the_corridor_the_criterion_closes_and_counts_both_searches():
    corridor = np.ones((5, 9), dtype=bool)
    corridor[2, :] = False  # one free row: every cell has a blocked cell within 1
    paper, p = ExtendedAStarPlanner(clearance=1), ExtendedAStarPlanner(clearance=1, fallback=True)
    for q in (paper, p):
        q.plan(corridor, (2, 8))
    assert paper.cost_at((2, 0)) >= INF
    _stats, path = p.update_and_path(np.empty(0, np.int64), np.empty(0, bool), (2, 0))
    assert len(path) == 9 and p.fallbacks == 1 and p.cost_at((2, 0)) == 80
    first_only = paper.search_stats
    assert first_only is not None and p.search_stats is not None
    assert p.search_stats.cells_touched > first_only.cells_touched
    p.path((2, 0))  # the same start and map: answered from the cache, no third search
    assert p.fallbacks == 1


@pytest.mark.parametrize("backend", ["cpu", "cuda", "reference", "auto"])
def test_the_registry_builds_it_on_the_cpu_for_every_backend(backend):
    p = make_planner("extended-astar", backend)
    assert isinstance(p, ExtendedAStarPlanner) and p.backend == "cpu"
    assert p.clearance == DEFAULT_CLEARANCE == 1 and p.fallback
    assert p.name == "extended-astar-cpu-d1-fallback"
    assert make_planner("extended-astar", "cpu", "paper").tie_break == "paper"
    with pytest.raises(ValueError):
        make_planner("extended-astar", "cpu", "nope")


@pytest.mark.filterwarnings("ignore::RuntimeWarning")  # medians of a walk of no steps
def test_the_bench_walks_with_it():
    from sim.benchmark import BenchConfig, run_bench

    result = run_bench(BenchConfig(grids=[50], unknowns=[0.4], modes=["astar", "extended-astar"]))
    rows = {r["mode"]: r for r in result.rows}
    ext = rows["extended-astar"]
    assert rows["astar"]["arrived"] and ext["planner"] == "extended-astar-cpu-d1-fallback"
    # At 50 cells the inflated courtyard leaves the start no neighbour 1 cell clear of an
    # obstacle: the memory criterion alone answers no path (the paper's form, below); the
    # fallback searches again without it, and the walk arrives.
    assert ext["arrived"] and ext["steps"] > 20


def test_the_study_counts_and_its_setups_are_well_formed():
    from sim.extended_astar_study import SETUP_GOAL, SETUP_SHAPE, SETUP_START, optimality, setup_map

    table = optimality([0.0, 0.2], 16, 4, 20, 0, "boxes")
    assert table.count("skip open only") == 2
    empty = [ln for ln in table.splitlines() if ln.strip().startswith("0.00")]
    assert all("0 (  0.0%)" in ln for ln in empty)  # an empty map: nothing missed, none longer
    sizes = []
    for name in "ABC":
        m = setup_map(name, 0)
        assert m.shape == SETUP_SHAPE and not m[SETUP_START] and not m[SETUP_GOAL]
        sizes.append(int(m.sum()))
        assert int(dijkstra_field(m, SETUP_GOAL)[SETUP_START]) < INF
    assert sizes[0] == 0 < sizes[1] < sizes[2]


class _Refusing(AStarPlanner):
    """An exact planner that answers no path from some cells, as extended A* may."""

    def __init__(self, refuse: set[tuple[int, int]]) -> None:
        super().__init__()
        self.refuse = refuse

    def path(self, start):  # type: ignore[override]
        return np.empty((0, 2), np.int32) if tuple(start) in self.refuse else super().path(start)


def test_the_escape_passes_over_an_exit_without_a_path():
    from daemon.planning.escape import escape_path
    from daemon.planning.grid import FREE

    blocked = np.zeros((15, 15), bool)
    blocked[7, 7] = True  # the user stands in the margin
    occupancy = np.full(blocked.shape, FREE, np.uint8)
    p = _Refusing(set())
    p.plan(blocked, (0, 7))
    path, cost = escape_path(p, blocked, occupancy, (7, 7), 3)
    assert tuple(path[1]) == (6, 7) and cost == 10 + 60
    p.refuse = {(6, 7)}
    path, cost = escape_path(p, blocked, occupancy, (7, 7), 3)
    assert tuple(path[1]) != (6, 7) and cost == path_cost(path) and cost < INF
    p.refuse = {(r, c) for r in range(15) for c in range(15)}
    path, cost = escape_path(p, blocked, occupancy, (7, 7), 3)
    assert path.shape == (0, 2) and cost == INF
