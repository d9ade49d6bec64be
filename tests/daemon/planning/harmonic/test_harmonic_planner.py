"""The harmonic planner's contract: descent reaches the goal from every reachable cell and
never enters a blocked one, no path where the goal is out of reach, a converged residual,
warm replans equal to cold plans, and no plateau where the paper's ``u`` has one."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from daemon.planning import make_planner
from daemon.planning.grid import INF, path_cost
from daemon.planning.harmonic import relax as rx
from daemon.planning.harmonic.planner import TOL

pytestmark = pytest.mark.timeout(120)

FIELD_TOL = 5e-3
"""Two relaxations of one map, each stopped at the residual tolerance (1e-4), agree on
``w`` within this (log units: 0.5 % of ``1 − u``); measured 2e-4 to 1e-3 here."""


def check_paths(planner, blocked: np.ndarray, reach: np.ndarray) -> None:
    goal = planner.goal
    for r, c in zip(*np.nonzero(~blocked), strict=True):
        path = planner.path((r, c))
        if not reach[r, c]:
            assert len(path) == 0 and planner.cost_at((r, c)) == INF
            continue
        assert len(path) >= 1, f"no path from reachable {(r, c)}"
        assert tuple(path[0]) == (r, c) and tuple(path[-1]) == goal
        assert not blocked[path[:, 0], path[:, 1]].any()
        assert planner.cost_at((r, c)) == path_cost(path)  # adjacent steps, or it raises


@settings(
    max_examples=25, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture]
)
@given(seed=st.integers(0, 2**31), h=st.integers(3, 24), w=st.integers(3, 24),
       density=st.floats(0.0, 0.45), variant=st.sampled_from(["fast", "paper"]))  # fmt: skip
def test_descent_reaches_the_goal_from_every_reachable_cell(maps, seed, h, w, density, variant):
    rng = np.random.default_rng(seed)
    blocked = maps.random_map(rng, h, w, density)
    goal = (int(rng.integers(0, h)), int(rng.integers(0, w)))
    blocked[goal] = False
    planner = make_planner("harmonic", "cpu", variant)
    planner.plan(blocked, goal)
    assert planner.residual < TOL
    check_paths(planner, blocked, maps.reachable(blocked, goal))
    # A few changes, each replanned from the last field: the contract holds after each.
    for _ in range(3):
        cells = rng.integers(0, h * w, size=int(rng.integers(1, 8)))
        values = rng.random(cells.size) < 0.6
        values[cells == goal[0] * w + goal[1]] = False
        planner.update(cells, values)
        blocked.reshape(-1)[cells] = values
        assert planner.reach.count == planner.reach.reach.sum()  # kept up, not summed
        # A step may stop before the tolerance, never on a field with a pit.
        assert planner.settled
        assert planner.residual < TOL or not rx.has_pit(
            planner.engine.w, planner.engine.fixed, planner.engine.width
        )
    check_paths(planner, blocked, maps.reachable(blocked, goal))
    planner.converge()
    assert planner.residual < TOL or planner.reach.count == 0
    check_paths(planner, blocked, maps.reachable(blocked, goal))


def test_a_blocked_or_cut_off_start_and_a_blocked_goal_get_no_path():
    blocked = np.zeros((12, 12), dtype=bool)
    blocked[5, :] = True  # a wall across: the top half cannot reach the goal below
    planner = make_planner("harmonic", "cpu")
    planner.plan(blocked, (10, 3))
    assert len(planner.path((2, 2))) == 0 and planner.cost_at((2, 2)) == INF
    assert len(planner.path((5, 2))) == 0
    assert len(planner.path((-1, 2))) == 0
    planner.update(np.array([5 * 12 + 7]), np.array([False]))  # a door opens
    path = planner.path((2, 2))
    assert tuple(path[-1]) == (10, 3) and (5, 7) in {tuple(p) for p in path}
    blocked[10, 3] = True
    planner.plan(blocked, (10, 3))
    assert len(planner.path((11, 11))) == 0


def test_warm_replans_equal_cold_plans_within_the_tolerance(maps):
    rng = np.random.default_rng(7)
    blocked = maps.random_map(rng, 40, 40, 0.15)
    goal = (2, 3)
    blocked[goal] = False
    warm = make_planner("harmonic", "cpu")
    warm.plan(blocked, goal)
    for step in range(6):
        # A person-sized block appears near the middle, and the last one goes.
        r, c = int(rng.integers(5, 35)), int(rng.integers(5, 35))
        cells = (np.arange(r, r + 4)[:, None] * 40 + np.arange(c, c + 4)[None, :]).ravel()
        cells = cells[cells != goal[0] * 40 + goal[1]]
        stats = warm.update(cells, True)
        assert stats.iterations < 2000, f"step {step}: {stats.iterations} sweeps"
        blocked.reshape(-1)[cells] = True
        freed = cells[rng.random(cells.size) < 0.5]
        warm.update(freed, False)
        blocked.reshape(-1)[freed] = False
    check_paths(warm, blocked, maps.reachable(blocked, goal))  # on the steps' field
    warm.converge()
    assert warm.residual < TOL
    cold = make_planner("harmonic", "cpu")
    cold.plan(blocked, goal)
    reach = maps.reachable(blocked, goal) & ~blocked
    a, b = warm.field()[reach], cold.field()[reach]
    assert np.abs(a - b).max() < FIELD_TOL
    assert (warm.field()[~reach] == rx.BLOCKED_W).all()


def test_no_plateau_in_log_space_where_the_papers_u_has_one(maps):
    # A winding corridor 3 cells wide: 1 − u falls by orders of magnitude per lane, below
    # float32's and float64's epsilon long before the far end (w reaches ~300 here).
    blocked, start, goal = maps.serpentine(64)
    reach = maps.reachable(blocked, goal)
    h, w = blocked.shape
    padded = np.ones((h + 2, w + 2), dtype=np.bool_)
    padded[1:-1, 1:-1] = blocked
    flat = padded.reshape(-1)
    g = (goal[0] + 1) * (w + 2) + goal[1] + 1
    fixed = flat.copy()
    fixed[g] = True
    preach = np.zeros(flat.size, dtype=np.int64) - 1
    preach.reshape(h + 2, w + 2)[1:-1, 1:-1] = np.where(reach, 1, -1)
    stuck = {}
    for dtype in (np.float32, np.float64):
        u = np.where(flat, 1.0, 0.5).astype(dtype)
        u[g] = 0
        rx.relax_linear(u, fixed, w + 2, rx.ORDER_RB, 1.9, 4000, 20, 0.0, np.empty_like(u))
        stuck[dtype.__name__] = rx.stuck_cells(u, w + 2, preach, g)
    planner = make_planner("harmonic", "cpu")
    planner.plan(blocked, goal)
    wfield = np.where(padded, rx.BLOCKED_W, 0.0).reshape(-1)
    wfield.reshape(h + 2, w + 2)[1:-1, 1:-1] = planner.field()
    assert planner.field()[start] > 40  # 1 − u < 1e-17: past float64's epsilon at the start
    assert stuck["float32"] > 0 and stuck["float64"] > 0
    assert rx.stuck_cells(wfield, w + 2, preach, g) == 0
    assert tuple(planner.path(start)[-1]) == goal


def test_the_papers_row_wise_form_and_jacobi_reach_the_same_field(maps):
    rng = np.random.default_rng(3)
    blocked = maps.random_map(rng, 20, 20, 0.2)
    blocked[0, 0] = False
    fast = make_planner("harmonic", "cpu", "fast")
    paper = make_planner("harmonic", "cpu", "paper")
    fast.plan(blocked, (0, 0))
    paper.plan(blocked, (0, 0))
    reach = maps.reachable(blocked, (0, 0)) & ~blocked
    assert np.abs(fast.field()[reach] - paper.field()[reach]).max() < FIELD_TOL
    assert fast.name == "harmonic-cpu" and paper.name == "harmonic-cpu-paper"


def test_two_far_apart_changes_that_only_together_cut_a_room_off():
    # A wall with two doors 50 cells apart (beyond each change's window): closing both in
    # one update cuts the top off, which neither cluster's own window can show as joined.
    blocked = np.zeros((6, 60), dtype=bool)
    blocked[2, :] = True
    blocked[2, 3] = blocked[2, 55] = False
    planner = make_planner("harmonic", "cpu")
    planner.plan(blocked, (5, 30))
    assert tuple(planner.path((0, 30))[-1]) == (5, 30)
    planner.update(np.array([2 * 60 + 3, 2 * 60 + 55]), np.array([True, True]))
    assert len(planner.path((0, 30))) == 0 and planner.cost_at((0, 30)) == INF
    assert planner.reach.count == planner.reach.reach.sum()
    planner.update(np.array([2 * 60 + 55]), np.array([False]))  # one door opens again
    assert tuple(planner.path((0, 30))[-1]) == (5, 30)


def test_a_goal_blocked_then_freed_again_is_the_goal_again():
    # A person stands on the goal, then leaves: the goal must hold u = 0 (w = 0) again.
    blocked = np.zeros((10, 10), dtype=bool)
    planner = make_planner("harmonic", "cpu")
    planner.plan(blocked, (2, 2))
    planner.update(np.array([22]), np.array([True]))
    assert len(planner.path((8, 8))) == 0
    planner.update(np.array([22]), np.array([False]))
    assert planner.field()[2, 2] == 0.0
    assert tuple(planner.path((8, 8))[-1]) == (2, 2)


def test_a_cell_named_twice_in_one_delta_takes_its_last_value():
    # The map's rule for a delta (``Reach.apply`` keeps it without sorting): the last wins.
    blocked = np.zeros((8, 8), dtype=bool)
    planner = make_planner("harmonic", "cpu")
    planner.plan(blocked, (0, 0))
    planner.update(np.array([27, 27, 28, 28, 36]), np.array([True, False, False, True, True]))
    field = planner.field()
    assert field[3, 3] < rx.BLOCKED_W and field[3, 4] == field[4, 4] == rx.BLOCKED_W
    assert not planner.reach.blocked[planner._flat((3, 3))]
    assert planner.reach.blocked[planner._flat((3, 4))]
    assert planner.reach.count == planner.reach.reach.sum() == 64 - 2


def test_the_whole_map_search_goes_to_an_engine_that_has_one(maps, monkeypatch):
    # An engine with ``reach_search_start`` (the GPU's) takes the reach's whole-map searches
    # on a map past DEVICE_SEARCH_CELLS: the same reach, field and descents as the host's.
    from daemon.planning.harmonic import HarmonicPlanner
    from daemon.planning.harmonic import planner as hp
    from daemon.planning.harmonic.cpu import CpuField

    calls = []

    class Searching(CpuField):
        def reach_search_start(self, blocked, before, goal):
            # Answered as the device does: from the masks as they were when it started.
            calls.append(goal)
            changed = np.flatnonzero(maps.flat_reachable(blocked, goal, self.width) != before)
            return lambda: changed

    monkeypatch.setattr(hp, "DEVICE_SEARCH_CELLS", 0)
    blocked = np.zeros((30, 30), dtype=bool)
    goal = (2, 2)
    handed, own = HarmonicPlanner(Searching()), HarmonicPlanner(CpuField())
    wall = 15 * 30 + np.arange(30)
    door = 15 * 30 + np.arange(20, 23)
    # A wall across (both sides finite: the whole-map search), a door in it, the goal walled in.
    steps = [(wall, True), (door, False), (np.array([1 * 30 + 2, 3 * 30 + 2]), True)]
    for planner in (handed, own):
        planner.plan(blocked, goal)
    for cells, value in steps:
        for planner in (handed, own):
            planner.update(cells, value)
        blocked.reshape(-1)[cells] = value
        assert (handed.reach.reach == own.reach.reach).all()
        assert handed.reach.count == own.reach.count == int(own.reach.reach.sum())
        assert np.array_equal(handed.field(), own.field())
        maps.descents_hold(handed, blocked, maps.reachable(blocked, goal), steps=True)
    assert len(calls) == handed.reach.full_searches >= 1


def test_an_engine_that_searches_has_the_answers_pass_run_at_plan_on_any_map(monkeypatch):
    # Only a device search's answer runs ``_answered``; the warm-up's map is too small to
    # search on the device, so ``plan`` runs it (compiled or loaded from numba's cache) for
    # any engine that can search, and the walk's first device search does not pay for it.
    from daemon.planning.harmonic import HarmonicPlanner
    from daemon.planning.harmonic import reach as hr
    from daemon.planning.harmonic.cpu import CpuField

    answered = []
    real = hr._answered
    monkeypatch.setattr(hr, "_answered", lambda *a: answered.append(a) or real(*a))

    class Searching(CpuField):
        def reach_search_start(self, blocked, before, goal):
            raise AssertionError("a 20² map searches on the host")

    blocked = np.zeros((20, 20), dtype=bool)
    HarmonicPlanner(CpuField()).plan(blocked, (2, 2))
    assert not answered
    planner = HarmonicPlanner(Searching())
    planner.plan(blocked, (2, 2))
    assert planner.reach.search is None and len(answered) == 1
    assert answered[0][0] is planner.reach.reach and answered[0][1].size == 0
    reach = planner.reach.reach.copy()
    planner.update(15 * 20 + np.arange(20), True)  # a wall across: the host's search
    assert (planner.reach.reach != reach).any() and len(answered) == 1
