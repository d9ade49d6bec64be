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
