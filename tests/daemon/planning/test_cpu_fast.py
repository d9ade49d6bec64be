"""What only the fast CPU planner has: its bucket queue's pool running out."""

from __future__ import annotations

import numpy as np

from daemon.planning.cpu.fast import FastCpuPlanner
from daemon.planning.dijkstra import dijkstra_field, reference_path


def test_a_queue_that_runs_out_grows_and_the_field_stays_exact():
    rng = np.random.default_rng(7)
    truth = rng.random((40, 40)) < 0.2
    goal = (0, 20)
    truth[goal] = False
    p = FastCpuPlanner(queue_capacity=2)
    p.plan(truth, goal)  # DSS overflows at once and is retried with a larger pool
    np.testing.assert_array_equal(p.costs(), dijkstra_field(truth, goal))
    p._pool = np.zeros((2, 2), np.int64)  # small again, so that an EDS update overflows
    wall = np.arange(5 * 40 + 2, 5 * 40 + 38)
    p.update(wall, np.ones(wall.size, bool))
    truth.reshape(-1)[wall] = True
    ref = dijkstra_field(truth, goal)
    np.testing.assert_array_equal(p.costs(), ref)
    np.testing.assert_array_equal(p.path((39, 0)), reference_path(ref, truth, (39, 0)))
    assert p._pool.shape[0] > 2
    p.update(wall[::3], np.zeros(wall[::3].size, bool))  # marks were cleared: EDS works again
    truth.reshape(-1)[wall[::3]] = False
    np.testing.assert_array_equal(p.costs(), dijkstra_field(truth, goal))


def test_a_cut_behind_the_user_waits_until_something_asks_for_it():
    """A wall west of the user's way, across an open field: every cell in its shadow costs
    more now, but the step repairs only those nearer the goal than the user; the rest of the
    raise waits in the queue, a query reaches what it reads, and ``settle`` finishes it."""
    n = 120
    truth = np.zeros((n, n), bool)
    goal, user = (0, 60), (40, 60)
    p = FastCpuPlanner()
    p.plan(truth, goal)
    wall = np.arange(20 * n, 20 * n + 50)  # row 20, columns 0..49
    truth.reshape(-1)[wall] = True
    stats, path = p.update_and_path(wall, np.ones(wall.size, bool), user)
    ref = dijkstra_field(truth, goal)
    np.testing.assert_array_equal(path, reference_path(ref, truth, user))
    assert p.pending() > 0, "cells behind the user were repaired in the step"
    assert stats.iterations < int(np.count_nonzero(ref != dijkstra_field(truth * 0 > 0, goal)))
    assert p.cost_at((n - 1, 0)) == int(ref[n - 1, 0])  # a query reaches what it reads
    p.settle()
    assert p.pending() == 0
    np.testing.assert_array_equal(p._interior(p._g), ref)  # the stored field, not a query


def test_a_repair_past_its_budget_computes_the_field_from_scratch():
    """A wall across the map, the user behind it: the repair would raise and lower nearly
    everything, so past its budget of expansions it gives up and computes the field whole (as
    many expansions as DSS), exactly, with nothing left queued; a small change stays a small
    repair afterwards."""
    n = 100
    truth = np.zeros((n, n), bool)
    goal, user = (0, 50), (n - 1, 50)
    eds, dss = FastCpuPlanner(cut_over=0.05), FastCpuPlanner(dss=True)
    eds.plan(truth, goal)
    dss.plan(truth, goal)
    wall = np.arange(10 * n, 10 * n + n - 1)  # row 10, open only at the east edge
    truth.reshape(-1)[wall] = True
    full, _ = dss.update_and_path(wall, np.ones(wall.size, bool), user)
    cut, path = eds.update_and_path(wall, np.ones(wall.size, bool), user)
    assert cut.iterations == full.iterations and eds.pending() == 0
    ref = dijkstra_field(truth, goal)
    np.testing.assert_array_equal(path, reference_path(ref, truth, user))
    np.testing.assert_array_equal(eds._interior(eds._g), ref)  # the stored field, not a query
    r, c = path[8]  # something appears on the way, eight cells ahead
    rows, cols = np.mgrid[r - 2 : r + 3, c - 2 : c + 3]
    box = (rows * n + cols).ravel()
    truth.reshape(-1)[box] = True
    small, path = eds.update_and_path(box, np.ones(box.size, bool), user)
    # The cells behind the box drop when it comes in (counted as touched); the user's way
    # around it costs the same, so lowering them again waits.
    assert small.cells_touched > 0 and small.iterations < full.iterations // 10
    np.testing.assert_array_equal(path, reference_path(dijkstra_field(truth, goal), truth, user))


def test_the_escape_window_is_exact_without_settling_the_whole_field():
    """``costs_within`` repairs what the window needs: its g equals Dijkstra's while cells
    elsewhere still wait."""
    n = 120
    truth = np.zeros((n, n), bool)
    goal, user = (0, 60), (40, 60)
    p = FastCpuPlanner()
    p.plan(truth, goal)
    wall = np.arange(20 * n, 20 * n + 50)
    truth.reshape(-1)[wall] = True
    p.update_and_path(wall, np.ones(wall.size, bool), user)
    window = p.costs_within(30, 51, 50, 71)
    np.testing.assert_array_equal(window, dijkstra_field(truth, goal)[30:51, 50:71])
    assert p.pending() > 0


def test_the_planner_state_of_a_2000_square_map_stays_under_100_mb():
    """Issue 20's memory bound: every array the EDS planner keeps, at 2000 x 2000."""
    p = FastCpuPlanner()
    p.plan(np.zeros((2000, 2000), bool), (0, 1000))
    arrays = [v for v in vars(p).values() if isinstance(v, np.ndarray)]
    assert sum(a.nbytes for a in arrays) < 100e6
