"""The closed-loop walk: it arrives, and EDS and DSS walk the same cells."""

from __future__ import annotations

import numpy as np
import pytest

from daemon.planning.grid import OCCUPIED
from sim.courtyard import make_courtyard
from sim.walk import walk
from sim.world import heading_along

pytestmark = pytest.mark.timeout(120)


def assert_valid_walk(scenario, result):
    steps = np.abs(np.diff(result.walked.astype(np.int64), axis=0))
    assert np.all(steps.max(axis=1) == 1)  # one neighbour cell per step
    rows, cols = result.walked[:, 0], result.walked[:, 1]
    # the user never stands in a real obstacle
    assert not np.any(scenario.true[rows, cols] == OCCUPIED)
    assert tuple(result.walked[0]) == scenario.start
    assert len(result.iterations) == len(result.step_ms) == len(result.nav_ms) == result.steps
    assert np.all(result.step_ms >= 0) and np.all(result.inflate_ms >= 0)
    # the navigator's whole step holds the planner's part of it
    assert np.all(result.nav_ms >= result.step_ms)


@pytest.mark.parametrize("unknown", [0.2, 0.6])
def test_eds_and_dss_walk_the_same_cells_to_the_goal(unknown):
    scenario = make_courtyard(grid=100, unknown=unknown, seed=5)
    eds = walk(scenario, backend="cpu", mode="eds")
    dss = walk(scenario, backend="cpu", mode="dss")
    assert eds.arrived and dss.arrived and eds.reason == "arrived"
    assert tuple(eds.walked[-1]) == scenario.goal
    assert np.array_equal(eds.walked, dss.walked)
    assert_valid_walk(scenario, eds)
    # what was learnt is the truth where seen, and the same for both modes
    assert np.array_equal(eds.known, dss.known)
    seen = eds.known != scenario.known
    assert np.all(eds.known[seen] == scenario.true[seen])
    assert eds.changed.sum() > 0 and eds.walked_m > 8.0


def test_the_cpu_walk_is_the_reference_planner_walk():
    scenario = make_courtyard(grid=50, unknown=0.4, seed=6)
    fast = walk(scenario, backend="cpu", mode="eds")
    ref = walk(scenario, backend="reference", mode="eds")
    assert fast.arrived and np.array_equal(fast.walked, ref.walked)


def test_an_all_round_sensor_also_arrives():
    scenario = make_courtyard(grid=100, unknown=0.4, seed=5)
    result = walk(scenario, backend="cpu", mode="eds", fov_deg=360)
    assert result.arrived
    assert_valid_walk(scenario, result)


def test_the_step_limit_stops_the_walk():
    scenario = make_courtyard(grid=100, unknown=0.2, seed=5)
    result = walk(scenario, backend="cpu", mode="eds", max_steps=10)
    assert not result.arrived and result.reason == "step limit" and result.steps == 10


def test_an_enclosed_goal_ends_with_no_path():
    base = make_courtyard(grid=50, unknown=0.0, seed=0)
    true = base.true.copy()
    r = base.goal[0]
    true[r + 4, :] = OCCUPIED  # a wall across the courtyard, unknown to the user
    scenario = type(base)(**{**base.__dict__, "true": true})
    result = walk(scenario, backend="cpu", mode="eds")
    assert result.reason == "no path" and not result.arrived
    assert result.walked[:, 0].min() > r + 4


def test_heading_follows_the_path_ahead():
    path = np.array([[10, 10], [9, 10], [8, 10], [7, 11]])
    assert heading_along(path, 2, 0.0) == pytest.approx(np.pi / 2)
    assert heading_along(path[:1], 2, 1.25) == 1.25


@pytest.mark.parametrize("name", ["courtyard", "explore"])
def test_a_walk_whose_steps_defer_blocks_walks_the_same_cells_and_gives_them_between_steps(name):
    """EDS with ``DeferredBlocks`` on (as on the device): the walk is the plain one, cell for
    cell; the blocks its steps deferred reach the planner between steps, so the repairing
    steps do exactly the plain walk's work."""
    from daemon.navigation import Navigator
    from daemon.planning import make_planner
    from daemon.planning.deferred_blocks import DeferredBlocks
    from daemon.planning.dijkstra import dijkstra_field
    from sim.scenarios import make_scenario
    from sim.walk import paper_settings

    scenario = make_scenario(name, 100, 0.4, 0)
    made: list[DeferredBlocks] = []

    def deferring(backend: str) -> DeferredBlocks:
        made.append(DeferredBlocks(make_planner("eds", backend), defer=True))
        return made[-1]

    settings = paper_settings(scenario, "eds", "cpu", "fast")
    nav = Navigator("walk", settings, planner_factory=deferring)
    deferred = walk(scenario, backend="cpu", mode="eds", navigator=nav)
    plain = walk(scenario, backend="cpu", mode="eds")
    assert deferred.arrived and np.array_equal(deferred.walked, plain.walked)
    wrapper = made[-1]
    assert wrapper.deferred_steps > 0
    wrapper.settle()  # what is still pending (the walk ended before its idle) goes first
    grid = nav.maps.map
    assert grid is not None and wrapper.pending_blocks() == 0
    np.testing.assert_array_equal(wrapper.costs(), dijkstra_field(grid.blocked, scenario.goal))
    repaired = deferred.iterations > 0  # the steps that reached the planner's repair
    np.testing.assert_array_equal(deferred.cells_touched[repaired], plain.cells_touched[repaired])
