"""The cuda planner against the CPU: the same field bit for bit after every update, the same path.

Runs only where cupy imports and a CUDA device answers (``pytest -m gpu`` on the GPU machine);
skipped cleanly elsewhere.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from daemon.planning import cuda_available, make_planner
from daemon.planning.dijkstra import dijkstra_field, reference_path
from daemon.planning.grid import INF

pytestmark = [
    pytest.mark.gpu,
    pytest.mark.skipif(not cuda_available(), reason="no usable CUDA device"),
]

# The product's form and the paper's Figure 4 form.
VARIANTS = ["fast", "paper"]
REPAIR = "fast-repair"
"""fast that never cuts over to a plan from scratch: on these small maps most EDS changes
would, so the comparison with the CPU after every update runs it too, to test the repair."""
SHAPES = [(1, 1), (1, 97), (83, 1), (2, 3), (37, 53), (64, 64), (65, 33), (100, 129)]


def cuda_planner(variant: str, dss: bool = False):
    from daemon.planning.cuda.planner import CudaPlanner

    if variant == REPAIR:
        return CudaPlanner("fast", dss=dss, cut_over=math.inf)
    return CudaPlanner(variant, dss=dss)


def random_map(rng, shape, density):
    blocked = rng.random(shape) < density
    goal = (int(rng.integers(shape[0])), int(rng.integers(shape[1])))
    blocked[goal] = False
    return blocked, goal


def random_delta(rng, blocked, goal, path):
    """A sensor-like local patch, scattered flips, cells of the current path, or the goal."""
    h, w = blocked.shape
    kind = rng.integers(5)
    if kind == 0:  # a disc around a random cell: obstacles appear or vanish together
        r = int(rng.integers(1, 8))
        cy, cx = int(rng.integers(h)), int(rng.integers(w))
        ys, xs = np.mgrid[max(cy - r, 0) : min(cy + r + 1, h), max(cx - r, 0) : min(cx + r + 1, w)]
        keep = (ys - cy) ** 2 + (xs - cx) ** 2 <= r * r
        cells = (ys[keep] * w + xs[keep]).ravel()
        values = rng.random(cells.size) < rng.choice([0.1, 0.5, 0.9])
    elif kind == 1:
        cells = rng.choice(h * w, size=min(h * w, int(rng.integers(1, 40))), replace=False)
        values = rng.random(cells.size) < 0.5
    elif kind == 2 and len(path) > 1:
        pick = rng.choice(len(path), size=min(len(path), 3), replace=False)
        cells = path[pick, 0].astype(np.int64) * w + path[pick, 1]
        values = np.ones(cells.size, bool)
    elif kind == 3:  # the goal closes or opens
        cells = np.array([goal[0] * w + goal[1]])
        values = np.array([not blocked[goal]])
    else:  # a wall across the map, sometimes with a gap
        row = int(rng.integers(h))
        cells = row * w + np.arange(w)
        values = np.ones(w, bool)
        if rng.random() < 0.5:
            values[rng.integers(w)] = False
    return np.asarray(cells, dtype=np.int64), np.asarray(values, dtype=bool)


@pytest.mark.timeout(600)
@pytest.mark.parametrize("variant", [*VARIANTS, REPAIR])
@pytest.mark.parametrize("shape", SHAPES, ids=lambda s: f"{s[0]}x{s[1]}")
def test_eds_and_dss_equal_cpu_after_every_update(variant, shape):
    rng = np.random.default_rng(hash(shape) % 2**32)
    cpu = make_planner("eds", "cpu", "fast")
    eds, dss = cuda_planner(variant), cuda_planner(variant, dss=True)
    blocked, goal = random_map(rng, shape, rng.choice([0.0, 0.2, 0.4]))
    start = (int(rng.integers(shape[0])), int(rng.integers(shape[1])))
    for p in (cpu, eds, dss):
        p.plan(blocked, goal)
    assert np.array_equal(eds.costs(), dijkstra_field(blocked, goal))
    for _ in range(12):
        cells, values = random_delta(rng, blocked, goal, cpu.path(start))
        blocked.reshape(-1)[cells] = values
        cpu.update(cells, values)
        s_eds = eds.update(cells, values)
        s_dss = dss.update(cells, values)
        truth = cpu.costs()
        assert np.array_equal(eds.costs(), truth)
        assert np.array_equal(dss.costs(), truth)
        assert np.array_equal(eds.blocked(), blocked)
        assert s_eds.ms > 0 and s_dss.iterations >= 1
        want = cpu.path(start)
        assert np.array_equal(eds.path(start), want)
        assert np.array_equal(dss.path(start), want)
        assert eds.cost_at(start) == cpu.cost_at(start)
    assert np.array_equal(eds.costs(), dijkstra_field(blocked, goal))


@pytest.mark.parametrize("variant", VARIANTS)
def test_path_follows_the_reference_rule_from_every_reachable_start(variant):
    rng = np.random.default_rng(7)
    blocked, goal = random_map(rng, (45, 70), 0.3)
    planner = cuda_planner(variant)
    planner.plan(blocked, goal)
    g = planner.costs()
    for start in zip(*np.nonzero(g < INF), strict=True):
        start = (int(start[0]), int(start[1]))
        if rng.random() < 0.1:
            assert np.array_equal(planner.path(start), reference_path(g, blocked, start))
    blocked_cell = tuple(int(v) for v in np.argwhere(blocked)[0])
    assert planner.path(blocked_cell).shape == (0, 2)
    assert planner.path((-1, 0)).shape == (0, 2)


def test_long_path_crosses_many_windows_and_the_chunk_limit():
    """A serpentine corridor: the path is far longer than the planner's path buffer."""
    h, w = 150, 150
    blocked = np.zeros((h, w), bool)
    for i, row in enumerate(range(2, h - 1, 3)):
        blocked[row, :] = True
        blocked[row, 0 if i % 2 else w - 1] = False
    for variant in VARIANTS:
        planner = cuda_planner(variant)
        planner.plan(blocked, (0, 0))
        start = (h - 1, w - 1)
        path = planner.path(start)
        assert len(path) > 4 * (h + w) + 1024  # beyond the planner's path buffer: continued
        assert np.array_equal(path, reference_path(planner.costs(), blocked, start))


def test_unreachable_and_blocked_goal():
    blocked = np.zeros((40, 40), bool)
    blocked[20, :] = True
    planner = cuda_planner("fast")
    planner.plan(blocked, (5, 5))
    assert planner.cost_at((30, 30)) == INF
    assert planner.path((30, 30)).shape == (0, 2)
    planner.update(np.array([5 * 40 + 5]), np.array([True]))  # the goal itself is blocked
    assert np.all(planner.costs() == INF)
    planner.update(np.array([5 * 40 + 5, 20 * 40 + 7]), np.array([False, False]))
    assert np.array_equal(planner.costs(), dijkstra_field(planner.blocked(), (5, 5)))


@pytest.mark.timeout(300)
@pytest.mark.parametrize("variant", ["fast", "paper"])
def test_large_map_matches_cpu_and_fits_in_100_mb(variant):
    import cupy as cp

    rng = np.random.default_rng(3)
    h = w = 2000 if variant == "fast" else 1000
    blocked = rng.random((h, w)) < 0.2
    goal = (5, w // 2)
    blocked[goal] = False
    pool = cp.get_default_memory_pool()
    before = pool.used_bytes()
    planner = cuda_planner(variant)
    planner.plan(blocked, goal)
    cpu = make_planner("eds", "cpu", "fast")
    cpu.plan(blocked, goal)
    assert np.array_equal(planner.costs(), cpu.costs())
    for _ in range(3):
        cy, cx = int(rng.integers(h)), int(rng.integers(w))
        ys, xs = np.mgrid[max(cy - 30, 0) : cy + 30, max(cx - 30, 0) : cx + 30]
        cells = (np.minimum(ys, h - 1) * w + np.minimum(xs, w - 1)).ravel()
        values = rng.random(cells.size) < 0.5
        cells, idx = np.unique(cells, return_index=True)
        planner.update(cells, values[idx])
        cpu.update(cells, values[idx])
        assert np.array_equal(planner.costs(), cpu.costs())
    used = pool.used_bytes() - before
    if variant == "fast":
        assert used < 100e6, f"{used / 1e6:.1f} MB on the device"
        assert planner.device_bytes() < 100e6
    assert np.array_equal(planner.path((h - 1, w // 2)), cpu.path((h - 1, w // 2)))


@pytest.mark.parametrize("variant", VARIANTS)
def test_a_new_plan_on_the_same_map_size_takes_the_new_goal(variant):
    """fast's resident loop keeps its arguments: the goal, like every other per-call value,
    must come from the call's parameters."""
    rng = np.random.default_rng(5)
    blocked, _ = random_map(rng, (70, 90), 0.25)
    planner = cuda_planner(variant)
    for goal in [(3, 4), (66, 80), (35, 1)]:
        blocked[goal] = False
        planner.plan(blocked, goal)
        assert np.array_equal(planner.costs(), dijkstra_field(blocked, goal))
        cells = rng.choice(70 * 90, size=30, replace=False)
        values = rng.random(30) < 0.5
        values[cells == goal[0] * 90 + goal[1]] = False
        blocked.reshape(-1)[cells] = values
        planner.update(cells, values)
        assert np.array_equal(planner.costs(), dijkstra_field(blocked, goal))
        start = (int(rng.integers(70)), int(rng.integers(90)))
        _, path = planner.update_and_path(np.empty(0, np.int64), np.empty(0, bool), start)
        assert np.array_equal(path, reference_path(planner.costs(), blocked, start))


@pytest.mark.timeout(120)
@pytest.mark.parametrize("variant", VARIANTS)
def test_deltas_beyond_the_stage_grow_it_and_stay_exact(variant):
    """A delta longer than the pinned stage moves it (fast: the resident loop is stopped and
    started on the new address; paper: the delta buffer grows); statistics and path come back
    every time."""
    rng = np.random.default_rng(9)
    h, w = 150, 170
    blocked, goal = random_map(rng, (h, w), 0.2)
    planner = cuda_planner(variant)
    planner.plan(blocked, goal)
    for size in (10, 2001, 3000, 20, 12000, 5):  # 2001: a stage of an odd length before
        cells = rng.choice(h * w, size=size, replace=False)
        values = rng.random(size) < 0.3
        values[cells == goal[0] * w + goal[1]] = False
        blocked.reshape(-1)[cells] = values
        start = (int(rng.integers(h)), int(rng.integers(w)))
        planner.dss = size == 20
        stats, path = planner.update_and_path(cells, values, start)
        g = dijkstra_field(blocked, goal)
        assert np.array_equal(planner.costs(), g), f"delta of {size}"
        assert np.array_equal(path, reference_path(g, blocked, start))
        assert stats.iterations >= 1 and (size < 1000 or stats.cells_touched > 0)


def test_encode_delta_keeps_the_last_value_of_a_cell_and_checks_bounds():
    from daemon.planning.cuda.device import encode_delta

    out = np.full(8, -1, np.int32)
    codes = encode_delta(np.array([5, 3, 5, 9]), np.array([True, False, False, True]), 10, out=out)
    assert codes.tolist() == [6, 10, 19] and out[:3].tolist() == [6, 10, 19]  # 5 -> last: free
    assert encode_delta(np.array([1, 2], np.int32), np.array(True), 10).tolist() == [3, 5]
    assert encode_delta(np.empty(0, np.int64), np.empty(0, bool), 10).size == 0
    for bad in ([10], [-1, 3]):
        with pytest.raises(IndexError):
            encode_delta(np.array(bad), np.ones(len(bad), bool), 10)
