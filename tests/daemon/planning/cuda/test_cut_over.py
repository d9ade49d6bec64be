"""The fast variant's cut-over: an EDS repair that raises more than ``cut_over`` cells gives up
on the device and computes the field from scratch in the same call; the field stays exact.

Runs only where a CUDA device answers (``pytest -m gpu``); skipped cleanly elsewhere.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from daemon.planning import cuda_available, make_planner
from daemon.planning.dijkstra import dijkstra_field, reference_path

pytestmark = [
    pytest.mark.gpu,
    pytest.mark.skipif(not cuda_available(), reason="no usable CUDA device"),
]


def test_a_big_raise_cuts_over_and_a_small_change_stays_a_repair():
    """A wall across the map raises everything behind it: past the limit the call gives up
    the repair and plans from scratch, exactly (the CPU's field, the reference Dijkstra's, the
    reference path in the same call); a delta that alone blocks more than the limit gives up
    before any raise round; a small change stays a repair, and the aborted raises left no
    raised cell or tile flag behind that could spoil it."""
    from daemon.planning.cuda.planner import CudaPlanner

    n = 200
    truth = np.zeros((n, n), bool)
    goal = (0, 100)
    eds, never = CudaPlanner("fast", cut_over=1.0), CudaPlanner("fast", cut_over=math.inf)
    cpu = make_planner("eds", "cpu", "fast")
    for p in (eds, never, cpu):
        p.plan(truth, goal)
    assert eds.cut_over == 2 * n and never.cut_over == n * n

    def change(cells: np.ndarray, value: bool, start=(n - 1, 0)) -> np.ndarray:
        values = np.full(cells.size, value)
        truth.reshape(-1)[cells] = value
        _, path = eds.update_and_path(cells, values, start)
        never.update(cells, values)
        cpu.update(cells, values)
        g = dijkstra_field(truth, goal)
        for p in (eds, never, cpu):
            np.testing.assert_array_equal(p.costs(), g)
        assert np.array_equal(path, reference_path(g, truth, start))
        return path

    wall = np.arange(20 * n, 20 * n + n - 1)  # row 20, open only at the east edge
    assert wall.size <= eds.cut_over  # the delta alone stays under the limit: a raise round cuts
    assert len(change(wall, True)) > n
    assert eds.cut_cells > eds.cut_over and eds.raised_cells == 0
    assert never.cut_cells == 0 and never.raised_cells > 50 * eds.cut_over

    box = np.array([100 * n + 50, 100 * n + 51])
    change(box, True)
    assert eds.cut_cells == 0 and 0 < eds.raised_cells <= eds.cut_over
    assert eds.raised_cells == never.raised_cells

    ys, xs = np.mgrid[150:175, 20:40]  # 500 cells blocked at once: more than the limit
    block = (ys * n + xs).ravel()
    change(block, True)
    assert eds.cut_cells >= block.size and eds.raised_cells == 0

    tiles = eds._flags.size // 7
    assert not eds._raised.get().any() and not eds._flags.get()[: 3 * tiles].any()
    change(box, False)  # freed cells: a repair that lowers, no raise
    assert eds.cut_cells == 0 and eds.raised_cells == 0
    change(wall[::2], False)
    assert eds.cut_cells == 0


@pytest.mark.timeout(60)
def test_a_cut_over_keeps_the_field_between_the_goal_and_the_change():
    """A wall across the far side of the map cuts over; the cells nearer the goal than any
    wall cell keep their g (cut_over.cuh), so the relaxation lowers the wall's shadow, not the
    whole map as a plan from scratch does; path, field and settle stay exact."""
    from daemon.planning.cuda.planner import CudaPlanner

    n = 256
    truth = np.zeros((n, n), bool)
    goal, user = (5, 128), (250, 5)
    eds, dss = CudaPlanner("fast"), CudaPlanner("fast", dss=True)
    for p in (eds, dss):
        p.plan(truth, goal)
    wall = np.arange(200 * n, 200 * n + n - 1)  # open only at the east edge
    truth.reshape(-1)[wall] = True
    values = np.ones(wall.size, bool)
    stats, path = eds.update_and_path(wall, values, user)
    full, _ = dss.update_and_path(wall, values, user)
    g = dijkstra_field(truth, goal)
    assert eds.cut_cells > eds.cut_over
    assert np.array_equal(path, reference_path(g, truth, user))
    assert full.cells_touched >= n * n - wall.size  # from scratch: every free cell
    assert stats.cells_touched < n * n // 2  # kept: the rows between goal and wall
    np.testing.assert_array_equal(eds.costs(), g)


@pytest.mark.timeout(60)
def test_two_cut_overs_beside_the_path_at_one_level_stay_exact():
    """Two boxes beside the walker's path, each a cut-over (a 32-cell tile grid of 4 x 6, the
    goal at the top's middle, the user in the bottom-left corner). The first's level is 1348;
    the second box lies at g >= 1468, yet its level is 1348 again, the least bound of what the
    first call deferred (in a Python model of the kernels' rules, not read off the device). A
    cut-over that ends a deferral without a visit to its tile leaves cells at INF beside finite
    ones for good (tail15's user's bound did: ~1200 cells in that model). Every path read is
    the reference path, and ``costs()`` is exact."""
    from daemon.planning.cuda.planner import CudaPlanner

    h, w, goal = 128, 192, (0, 96)
    boxes = (((112, 118), (20, 40)), ((118, 124), (14, 34)))
    p = CudaPlanner("fast", cut_over=0.0)
    truth = np.zeros((h, w), bool)
    user = (127, 0)
    p.plan(truth, goal)
    _, path = p.update_and_path(np.empty(0, np.int64), np.empty(0, bool), user)
    for (y0, y1), (x0, x1) in boxes:
        rr, cc = np.mgrid[y0:y1, x0:x1]
        cells = (rr * w + cc).ravel()
        assert not np.isin(cells, path[:, 0] * w + path[:, 1]).any(), "beside the path"
        truth.reshape(-1)[cells] = True
        g = dijkstra_field(truth, goal)
        _, path = p.update_and_path(cells, np.ones(cells.size, bool), user)
        assert p.cut_cells > p.cut_over, "each box cuts over"
        assert np.array_equal(path, reference_path(g, truth, user))
        user = tuple(int(v) for v in path[3])
    np.testing.assert_array_equal(p.costs(), dijkstra_field(truth, goal))
