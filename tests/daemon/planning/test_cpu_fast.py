"""What only the fast CPU planner has: its bucket queue's pool running out."""

from __future__ import annotations

import numpy as np

from daemon.planning.cpu import dial
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


def test_a_repair_that_raises_too_much_computes_the_field_from_scratch():
    """A wall across the map raises everything behind it: past the cut-over EDS gives up the
    repair and computes the field whole (as many expansions as DSS), exactly; a small change
    stays a repair, and the aborted raise left no marks behind that could spoil it."""
    n = 100
    truth = np.zeros((n, n), bool)
    goal = (0, 50)
    eds, dss = FastCpuPlanner(), FastCpuPlanner(dss=True)
    eds.plan(truth, goal)
    dss.plan(truth, goal)
    wall = np.arange(10 * n, 10 * n + n - 1)  # row 10, open only at the east edge
    truth.reshape(-1)[wall] = True
    full = dss.update(wall, np.ones(wall.size, bool))
    cut = eds.update(wall, np.ones(wall.size, bool))
    assert cut.iterations == full.iterations
    np.testing.assert_array_equal(eds.costs(), dijkstra_field(truth, goal))
    box = np.array([50 * n + 50, 50 * n + 51])
    truth.reshape(-1)[box] = True
    small = eds.update(box, np.ones(box.size, bool))
    assert 0 < small.iterations < full.iterations // 10
    np.testing.assert_array_equal(eds.costs(), dijkstra_field(truth, goal))
    assert not eds._ws[:, dial.MARK].any() and not eds._ws[:, dial.QUEUED].any()
