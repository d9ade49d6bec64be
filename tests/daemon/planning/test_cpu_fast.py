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
