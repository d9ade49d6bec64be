"""The user's bound (``kernels/user_bound.cuh``): a step whose user stands on the last path,
which its delta leaves open, decides the focused repair's deferrals against that path's cost
as well as the user's g, so a cut-over, which resets the user's g, still defers from its first
visit; the path read stays the reference path.

Runs only where a CUDA device answers (``pytest -m gpu``); skipped cleanly elsewhere. The
host's half (which call is named) is in ``test_host_protocol.py``.
"""

from __future__ import annotations

from datetime import timedelta

import numpy as np
import pytest
from hypothesis import HealthCheck, Phase, given, settings
from hypothesis import strategies as st

from daemon.planning import cuda_available
from daemon.planning.dijkstra import dijkstra_field, reference_path
from daemon.planning.grid import INF

pytestmark = [
    pytest.mark.gpu,
    pytest.mark.skipif(not cuda_available(), reason="no usable CUDA device"),
]


def planners(cut_over: float | None = None):
    """A planner, and one that never names the last path: the repair without the bound."""
    from daemon.planning.cuda.planner import CudaPlanner

    class Unbounded(CudaPlanner):
        def _finish_step(self, step: tuple, t0: float) -> tuple:
            out = super()._finish_step(step, t0)
            self._last_path = 0
            return out

    return CudaPlanner("fast", cut_over=cut_over), Unbounded("fast", cut_over=cut_over)


@pytest.mark.timeout(60)
def test_a_cut_over_beside_the_users_path_defers_with_the_bound_and_stays_exact():
    """A wall beside the user's path raises its whole shadow: the call cuts over and resets
    the user's g with everything above the wall's level. The last path is untouched, so the
    relaxation defers the tiles far from the user from its first visit: fewer visits than
    without the bound, the same reference path. A wall across the path then gives no bound
    (the path ahead is closed) and the step is exact too, as is the field after settle."""
    from daemon.planning.cuda import abi

    n = 256
    truth = np.zeros((n, n), bool)
    goal, user = (5, 128), (250, 128)
    bounded, unbounded = planners()
    none = np.empty(0, np.int64), np.empty(0, bool)
    for p in (bounded, unbounded):
        p.plan(truth, goal)
        _, path = p.update_and_path(*none, user)
    user = tuple(int(v) for v in path[3])  # three cells up the straight path
    wall = np.arange(200 * n, 200 * n + 101)  # row 200, columns 0-100: west of the path
    truth.reshape(-1)[wall] = True
    g = dijkstra_field(truth, goal)
    tiles = []
    for p in (bounded, unbounded):
        _, path = p.update_and_path(wall, np.ones(wall.size, bool), user)
        assert p.cut_cells > p.cut_over, "the wall's shadow passes the limit"
        assert np.array_equal(path, reference_path(g, truth, user))
        tiles.append(p.tiles)
    assert bounded._stage.array[abi.PARAM_LAST_PATH] != 0
    assert unbounded._stage.array[abi.PARAM_LAST_PATH] == 0
    assert tiles[0] < tiles[1], f"tile visits with / without the bound: {tiles}"

    across = np.arange(150 * n + 60, 150 * n + 200)  # row 150 across the path, open at the ends
    truth.reshape(-1)[across] = True
    g = dijkstra_field(truth, goal)
    user = tuple(int(v) for v in path[2])
    for p in (bounded, unbounded):
        _, path = p.update_and_path(across, np.ones(across.size, bool), user)
        assert np.array_equal(path, reference_path(g, truth, user))
        np.testing.assert_array_equal(p.costs(), g)


@pytest.mark.timeout(60)
def test_a_second_cut_over_at_the_first_ones_level_keeps_the_tiles_it_put_aside():
    """Two boxes beside the path, each a cut-over (a 32-cell tile grid of 4 x 6, the goal at the
    top's middle, the user in the bottom-left corner). The first's level, 1348, splits the
    cells at or above it into two pockets, the bottom corners; the right one lies beyond the
    user's bound, so its tiles are put aside with lb = 1348, their cells at INF next to kept
    cells below 1348. The second box lies at g >= 1468, so the least lb sets its level: 1348
    again. That resets nothing in the right pocket's tiles and they hold no changed cell: a
    cut-over that dropped their deferral would leave ~1200 cells at INF for good (cut_over.cuh,
    (5); tail15's rule did, in a Python model of the kernels' rules). Every path read is the
    reference path and ``costs()`` is exact, with the bound and without it."""
    h, w, goal = 128, 192, (0, 96)
    boxes = (((112, 118), (20, 40)), ((118, 124), (14, 34)))
    for p in planners(cut_over=0.0):
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


def path_cost(path: np.ndarray) -> int:
    steps = np.abs(np.diff(path, axis=0)).sum(axis=1)
    return int(np.where(steps == 2, 14, 10).sum())


def ahead_delta(data, truth: np.ndarray, path: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """What a walk senses: a box on the path ahead (the bound must go), a box beside it, a
    wall across the map with or without a gap (both may cut over), or cells freed."""
    h, w = truth.shape
    kind = data.draw(st.sampled_from(["on_path", "beside", "wall", "free"]), label="kind")
    if kind == "wall":
        row = data.draw(st.integers(0, h - 1), label="row")
        cells = row * w + np.arange(w)
        if data.draw(st.booleans(), label="gap"):
            gap = data.draw(st.integers(0, w - 4), label="gap_at")
            cells = np.delete(cells, np.arange(gap, gap + 3))
        return cells, np.ones(cells.size, bool)
    if kind == "on_path" and len(path) > 3:
        y, x = path[data.draw(st.integers(2, len(path) - 1), label="at")]
    else:
        y, x = data.draw(st.integers(0, h - 1), label="y"), data.draw(st.integers(0, w - 1))
    size = data.draw(st.integers(1, 6), label="size")
    rr, cc = np.mgrid[max(0, y - size) : min(h, y + size), max(0, x - size) : min(w, x + size)]
    cells = (rr * w + cc).ravel()
    return cells, np.full(cells.size, kind != "free")


# Bounded on a failure too: a deadline per example and no shrinking (a failing example is
# reported as found; shrinking builds a planner per try and ran past the device's step limit).
@pytest.mark.timeout(150)
@pytest.mark.parametrize("cut_over", [None, 0.0], ids=["default", "always_cut"])
@settings(
    max_examples=15,
    deadline=timedelta(seconds=30),
    phases=(Phase.explicit, Phase.reuse, Phase.generate),
    suppress_health_check=[HealthCheck.too_slow],
)
@given(data=st.data())
def test_a_walk_along_its_paths_reads_the_reference_path_at_every_step(cut_over, data):
    """The user walks a few cells along each path read, with no other call between steps
    (so every step may use the bound) but now and then an ``update`` (which drops it), while
    boxes land on the path ahead or beside it and walls cross the map: every path read is the
    reference path and costs the user's exact g; at the end ``costs()`` is exact.
    ``always_cut``: nearly every raising step cuts over, where the bound matters most."""
    from daemon.planning.cuda.planner import CudaPlanner

    h, w = data.draw(st.integers(64, 128), label="h"), data.draw(st.integers(64, 128), label="w")
    rng = np.random.default_rng(data.draw(st.integers(0, 2**32 - 1), label="seed"))
    truth = rng.random((h, w)) < data.draw(st.sampled_from([0.0, 0.1, 0.2]), label="density")
    goal = (data.draw(st.integers(0, h - 1)), data.draw(st.integers(0, w - 1)))
    user = (data.draw(st.integers(0, h - 1)), data.draw(st.integers(0, w - 1)))
    truth[goal] = truth[user] = False
    eds = CudaPlanner("fast", cut_over=cut_over)
    eds.plan(truth, goal)
    path = np.empty((0, 2), np.int32)
    for _ in range(data.draw(st.integers(2, 8), label="steps")):
        cells, values = ahead_delta(data, truth, path)
        values[(cells == goal[0] * w + goal[1]) | (cells == user[0] * w + user[1])] = False
        truth.reshape(-1)[cells] = values
        g = dijkstra_field(truth, goal)
        if data.draw(st.integers(0, 5), label="no_path") == 0:
            eds.update(cells, values)
            continue
        _, path = eds.update_and_path(cells, values, user)
        assert np.array_equal(path, reference_path(g, truth, user))
        if len(path) > 1:
            assert path_cost(path) == int(g[user])
            step = data.draw(st.integers(0, min(6, len(path) - 1)), label="walk")
            user = tuple(int(v) for v in path[step])
        else:
            assert g[user] >= INF or tuple(user) == goal
    np.testing.assert_array_equal(eds.costs(), dijkstra_field(truth, goal))
