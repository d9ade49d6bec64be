"""The fast variant's focused EDS repair (fast.cu): a walking step settles only the tiles whose
key g + h(user, ·) can still improve the user's path, and defers the rest.

The contract, both halves: the path read in a step is ``reference_path`` of the current map,
tie for tie, at every step, deferred tiles or not; ``costs()`` (which settles first) is the
reference Dijkstra's field. Maps here span many 32 x 32 tiles, so steps do defer (the property
tests of ``test_planner_properties.py`` draw maps of at most 2 x 2 tiles). Runs only where a
CUDA device answers (``pytest -m gpu``).
"""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from daemon.planning import cuda_available
from daemon.planning.dijkstra import dijkstra_field, reference_path
from daemon.planning.grid import INF

pytestmark = [
    pytest.mark.gpu,
    pytest.mark.skipif(not cuda_available(), reason="no usable CUDA device"),
]


def path_cost(path: np.ndarray) -> int:
    steps = np.abs(np.diff(path, axis=0)).sum(axis=1)
    return int(np.where(steps == 2, 14, 10).sum())


@pytest.mark.timeout(60)
def test_a_step_near_the_goal_defers_the_far_side_and_settle_finishes_it():
    """A wall reopened far behind a user who stands near the goal lowers a whole region that
    no path of the user's crosses: the step reads the exact path and defers that region;
    ``costs()`` then settles it and equals Dijkstra, and nothing stays deferred."""
    from daemon.planning.cuda.planner import CudaPlanner

    n = 256
    truth = np.zeros((n, n), bool)
    truth[100, :] = True  # the south is cut off by a wall
    goal, user = (5, 128), (20, 128)
    eds = CudaPlanner("fast")
    full = CudaPlanner("fast", focused=False)
    for p in (eds, full):
        p.plan(truth, goal)
    cells = np.arange(100 * n, 101 * n)
    truth[100, :] = False
    _, path = eds.update_and_path(cells, np.zeros(n, bool), user)
    full.update_and_path(cells, np.zeros(n, bool), user)
    g = dijkstra_field(truth, goal)
    assert np.array_equal(path, reference_path(g, truth, user))
    assert path_cost(path) == int(g[user])
    # the tiles of the reopened row are seeds, visited; the row of tiles south of them waits
    assert eds.deferred_tiles() >= n // 32 and full.deferred_tiles() == 0
    assert eds.tiles < full.tiles  # the focused step visited fewer tiles
    np.testing.assert_array_equal(eds.costs(), g)
    assert eds.deferred_tiles() == 0
    np.testing.assert_array_equal(full.costs(), g)


@st.composite
def walks(draw):
    """A map of several tiles a side, goal and user, and the deltas of a walk."""
    h, w = draw(st.integers(40, 160)), draw(st.integers(40, 160))
    rng = np.random.default_rng(draw(st.integers(0, 2**32 - 1)))
    truth = rng.random((h, w)) < draw(st.sampled_from([0.0, 0.1, 0.25]))
    goal = (draw(st.integers(0, h - 1)), draw(st.integers(0, w - 1)))
    user = (draw(st.integers(0, h - 1)), draw(st.integers(0, w - 1)))
    truth[goal] = truth[user] = False
    return truth, goal, user


def draw_delta(data, truth: np.ndarray, walls: list[np.ndarray]) -> tuple[np.ndarray, np.ndarray]:
    """A wall across the map (with or without a gap), a wall reopened, or a box, set,
    cleared or mixed (some cells freed, some blocked in one delta, as a sensor sweep reports
    them): changes that raise or lower regions far from the user as well as near."""
    h, w = truth.shape
    kind = data.draw(st.sampled_from(["wall", "reopen", "box", "mixed"]), label="kind")
    if kind == "reopen" and walls:
        cells = walls.pop(data.draw(st.integers(0, len(walls) - 1), label="which"))
        return cells, np.zeros(cells.size, bool)
    if kind in ("wall", "reopen"):
        at = data.draw(st.integers(0, h - 1), label="row")
        cells = at * w + np.arange(w)
        if data.draw(st.booleans(), label="gap"):
            gap = data.draw(st.integers(0, w - 1), label="gap_at")
            cells = np.delete(cells, np.arange(gap, min(w, gap + 3)))
        walls.append(cells)
        return cells, np.ones(cells.size, bool)
    r0, c0 = data.draw(st.integers(0, h - 1)), data.draw(st.integers(0, w - 1))
    rr, cc = np.mgrid[r0 : min(h, r0 + 12), c0 : min(w, c0 + 12)]
    cells = (rr * w + cc).ravel()
    if kind == "mixed":
        seed = data.draw(st.integers(0, 2**32 - 1), label="mix")
        return cells, np.random.default_rng(seed).random(cells.size) < 0.5
    return cells, np.full(cells.size, data.draw(st.booleans(), label="block"))


@pytest.mark.timeout(300)
@pytest.mark.parametrize("cut_over", [None, 0.0], ids=["default", "always_cut"])
@settings(max_examples=40, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(world=walks(), data=st.data())
def test_every_step_reads_the_reference_path_and_the_field_settles_exact(cut_over, world, data):
    """A walk of focused steps: after each delta the path read is the reference path tie
    for tie and costs the user's exact g; now and then a step reads no path (``update``, still
    focused on the last user cell) or a path from elsewhere; at the end ``costs()`` is exact.
    ``always_cut``: a limit of a few cells, so nearly every raising step gives the repair up
    and keeps only the old field below the change (cut_over.cuh), deferred tiles and all."""
    from daemon.planning.cuda.planner import CudaPlanner

    truth, goal, user = world
    eds = CudaPlanner("fast", cut_over=cut_over)
    eds.plan(truth, goal)
    walls: list[np.ndarray] = []
    for _ in range(data.draw(st.integers(1, 8), label="steps")):
        cells, values = draw_delta(data, truth, walls)
        truth.reshape(-1)[cells] = values
        g = dijkstra_field(truth, goal)
        if data.draw(st.integers(0, 4), label="no_path") == 0:
            eds.update(cells, values)
            continue
        _, path = eds.update_and_path(cells, values, user)
        assert np.array_equal(path, reference_path(g, truth, user))
        if len(path) > 1:
            assert path_cost(path) == int(g[user])
            user = tuple(int(v) for v in path[data.draw(st.integers(0, len(path) - 1))])
        elif g[user] >= INF and not truth[user]:
            assert len(path) == 0
        other = (data.draw(st.integers(0, truth.shape[0] - 1)),
                 data.draw(st.integers(0, truth.shape[1] - 1)))  # fmt: skip
        assert np.array_equal(eds.path(other), reference_path(g, truth, other))
    np.testing.assert_array_equal(eds.costs(), dijkstra_field(truth, goal))
    assert eds.deferred_tiles() == 0
