"""``update_and_path``: one replanning step (repair + path) in one call.

CPU planners take the interface's default (update or replan, then path); the fallback forwards
the call and replays it on the CPU after a device error; on the GPU (``-m gpu``) the cuda
planner's fused call (one synchronisation) gives the same field and path, bit for bit, as
separate calls and as the reference Dijkstra.
"""

from __future__ import annotations

import numpy as np
import pytest

from daemon.planning import cuda_available, make_planner
from daemon.planning.dijkstra import dijkstra_field
from daemon.planning.fallback import DeviceFault, FallbackPlanner
from daemon.planning.interface import UpdateStats, reference_path
from daemon.planning.reference import ReferencePlanner


def steps(seed: int, shape=(30, 40), n=8, size=25):
    rng = np.random.default_rng(seed)
    blocked = rng.random(shape) < 0.25
    h, w = shape
    goal = (min(1, h - 1), min(2, w - 1))
    blocked[goal] = False
    deltas = []
    for _ in range(n):
        cells = rng.choice(h * w, size=size, replace=False)
        start = (int(rng.integers(h)), int(rng.integers(w)))
        deltas.append((cells, rng.random(size) < 0.5, start))
    return blocked, goal, deltas


def serpentine(h: int = 64, w: int = 64) -> tuple[np.ndarray, tuple[int, int], tuple[int, int]]:
    """Walls across every other row, alternating gaps: a path of ~h*w/2 cells (longer than the
    device path buffer's first guess and its capacity, so the read-back is chunked)."""
    blocked = np.zeros((h, w), bool)
    for r in range(1, h, 2):
        blocked[r, :] = True
        blocked[r, w - 1 if r % 4 == 1 else 0] = False
    return blocked, (0, 0), (h - 2, w // 2)


@pytest.mark.timeout(60)
@pytest.mark.parametrize("backend,variant", [("cpu", "fast"), ("cpu", "paper"), ("reference", "")])
def test_default_equals_update_then_path(backend, variant):
    blocked, goal, deltas = steps(0)
    fused = make_planner(backend, variant or "fast")
    split = make_planner(backend, variant or "fast")
    truth = blocked.copy()
    fused.plan(blocked, goal)
    split.plan(blocked, goal)
    for i, (cells, values, start) in enumerate(deltas):
        full = i % 2 == 1
        truth.reshape(-1)[cells] = values
        stats, path = fused.update_and_path(cells, values, start, full=full)
        want = (split.replan if full else split.update)(cells, values)
        assert isinstance(stats, UpdateStats) and stats.ms >= 0
        assert (stats.iterations, stats.cells_touched) == (want.iterations, want.cells_touched)
        g = dijkstra_field(truth, goal)
        assert np.array_equal(fused.costs(), g)
        assert np.array_equal(path, split.path(start))
        assert np.array_equal(path, reference_path(g, truth, start))


class CountingPlanner(ReferencePlanner):
    """Records which methods were called; raises ``fault`` on the n-th ``update_and_path``."""

    name = "counting"

    def __init__(self, nth: int = 0, fault: BaseException | None = None) -> None:
        super().__init__()
        self.calls: list[str] = []
        self.left, self.fault = nth, fault

    def update_and_path(self, cells, blocked, start, *, full=False):
        self.calls.append("full" if full else "eds")
        self.left -= 1
        if self.left == 0 and self.fault is not None:
            raise self.fault
        return super().update_and_path(cells, blocked, start, full=full)


@pytest.mark.timeout(60)
def test_fallback_forwards_the_fused_call():
    blocked, goal, deltas = steps(1)
    inner = CountingPlanner()
    planner = FallbackPlanner(inner, cpu_factory=lambda: make_planner("reference"))
    planner.plan(blocked, goal)
    for i, (cells, values, start) in enumerate(deltas[:4]):
        planner.update_and_path(cells, values, start, full=i == 3)
    assert inner.calls == ["eds", "eds", "eds", "full"]
    assert planner.active_backend == "cuda"


@pytest.mark.timeout(60)
@pytest.mark.parametrize("nth", [1, 3])
def test_fallback_replays_a_failed_fused_step_on_the_cpu(nth):
    blocked, goal, deltas = steps(2)
    inner = CountingPlanner(nth, DeviceFault("injected"))
    planner = FallbackPlanner(inner, cpu_factory=lambda: make_planner("cpu"))
    truth = blocked.copy()
    planner.plan(blocked, goal)
    for i, (cells, values, start) in enumerate(deltas):
        truth.reshape(-1)[cells] = values
        _, path = planner.update_and_path(cells, values, start, full=i % 3 == 2)
        assert planner.active_backend == ("cuda" if i + 1 < nth else "cpu")
        g = dijkstra_field(truth, goal)
        assert np.array_equal(planner.costs(), g)
        assert np.array_equal(path, reference_path(g, truth, start))
    assert "injected" in planner.fallback_reason


# -- on the GPU -------------------------------------------------------------------------------

CONFIGS = [
    pytest.param(("fast", {}), id="fast"),
    pytest.param(("fast", {"sched": 0}), id="fast-rounds"),
    pytest.param(("fast", {"max_blocks": 3}), id="fast-3blocks"),
    pytest.param(("fast", {"resident": False}), id="fast-graph"),
    pytest.param(("fast", {"resident": False, "use_graph": False}), id="fast-direct"),
    pytest.param(("fast", {"path_mode": "walk"}), id="fast-walkpath"),
    pytest.param(("paper", {}), id="paper"),
]


def cuda_planner(config):
    from daemon.planning.cuda_planner import CudaPlanner

    variant, kw = config
    return CudaPlanner(variant, **kw)


@pytest.mark.gpu
@pytest.mark.timeout(300)
@pytest.mark.skipif(not cuda_available(), reason="no usable CUDA device")
@pytest.mark.parametrize("config", CONFIGS)
@pytest.mark.parametrize("shape", [(1, 1), (37, 53), (100, 129)], ids=lambda s: f"{s[0]}x{s[1]}")
@pytest.mark.parametrize("seed", [0, 1])
def test_fused_equals_separate_calls_bit_exact(config, shape, seed):
    n = max(1, min(40, shape[0] * shape[1] // 4))
    blocked, goal, deltas = steps(seed, shape, n=30, size=n)
    fused, split = cuda_planner(config), cuda_planner(config)
    truth = blocked.copy()
    fused.plan(blocked, goal)
    split.plan(blocked, goal)
    h = shape[0]
    for i, (cells, values, start) in enumerate(deltas):
        full = i % 4 == 3
        if i % 7 == 5:
            start = (h + 3, -1)  # off the map: an empty path, the statistics still read
        truth.reshape(-1)[cells] = values
        if i % 5 == 4:  # separate calls on the fused planner too: the barrier count carries
            (fused.replan if full else fused.update)(cells, values)
            path = fused.path(start)
        else:
            stats, path = fused.update_and_path(cells, values, start, full=full)
            assert stats.iterations >= 0 and stats.cells_touched >= 0 and stats.ms > 0
            assert getattr(fused, "last_stats", stats) is stats
        (split.replan if full else split.update)(cells, values)
        g = dijkstra_field(truth, goal)
        assert np.array_equal(fused.costs(), g), f"step {i}"
        assert np.array_equal(fused.costs(), split.costs())
        assert np.array_equal(path, split.path(start))
        assert np.array_equal(path, reference_path(g, truth, start))


@pytest.mark.gpu
@pytest.mark.timeout(120)
@pytest.mark.skipif(not cuda_available(), reason="no usable CUDA device")
@pytest.mark.parametrize("path_mode", ["tiles", "walk"])
def test_fused_long_path_is_read_back_in_chunks(path_mode):
    from daemon.planning.cuda_planner import CudaPlanner

    blocked, goal, start = serpentine()
    planner = CudaPlanner("fast", path_mode=path_mode)
    planner.plan(blocked, goal)
    g = dijkstra_field(blocked, goal)
    want = reference_path(g, blocked, start)
    assert len(want) > 1500  # beyond the first guess (256) and the buffer (1536 cells here)
    flip = np.array([5 * 64 + 10]), np.array([False])  # a gap in a wall near the goal
    blocked.reshape(-1)[flip[0]] = False
    for full in (False, True):
        stats, path = planner.update_and_path(*flip, start, full=full)
        g = dijkstra_field(blocked, goal)
        assert np.array_equal(planner.costs(), g)
        assert np.array_equal(path, reference_path(g, blocked, start))
        assert stats.iterations >= 1


@pytest.mark.gpu
@pytest.mark.timeout(300)
@pytest.mark.skipif(not cuda_available(), reason="no usable CUDA device")
@pytest.mark.parametrize("config", CONFIGS[:4])  # the fused path: fast with tiles
def test_fused_walk_with_local_changes_keeps_the_exits_it_reuses_exact(config):
    """A walk along the path with sensor-like discs of change: most tiles keep their cached
    exits from step to step, and the path must still be the reference path every time."""
    rng = np.random.default_rng(11)
    h, w = 200, 300
    blocked = rng.random((h, w)) < 0.3
    goal = (5, 5)
    blocked[goal] = False
    planner = cuda_planner(config)
    planner.plan(blocked, goal)
    start = (h - 3, w - 3)
    blocked[start] = False
    planner.update(np.array([start[0] * w + start[1]]), np.array([False]))
    tiles = -(-h // 32) * -(-w // 32)
    recomputed = []
    for i in range(60):
        cy, cx = int(rng.integers(h)), int(rng.integers(w))
        if i % 3 == 0:  # often right on the path, which cuts it
            path_now = planner.path(start)
            if len(path_now) > 4:
                cy, cx = (int(v) for v in path_now[len(path_now) // 3])
        r = int(rng.integers(1, 6))
        ys, xs = np.mgrid[max(cy - r, 0) : min(cy + r + 1, h), max(cx - r, 0) : min(cx + r + 1, w)]
        cells = (ys * w + xs).ravel()
        values = rng.random(cells.size) < 0.6
        values[cells == start[0] * w + start[1]] = False
        values[cells == goal[0] * w + goal[1]] = False
        blocked.reshape(-1)[cells] = values
        full = i % 10 == 9
        _, path = planner.update_and_path(cells, values, start, full=full)
        if full:
            assert planner.exit_tiles == tiles  # a plan from scratch changes every tile
        else:
            recomputed.append(planner.exit_tiles)
        g = dijkstra_field(blocked, goal)
        assert np.array_equal(planner.costs(), g), f"step {i}"
        assert np.array_equal(path, reference_path(g, blocked, start)), f"step {i}"
        if len(path) > 3:
            start = (int(path[3][0]), int(path[3][1]))  # the user walks on
    # a local change leaves most tiles' exits as they were (the start's tile is always redone)
    assert min(recomputed) >= 1 and np.median(recomputed) < tiles / 2, recomputed


@pytest.mark.gpu
@pytest.mark.timeout(60)
@pytest.mark.skipif(not cuda_available(), reason="no usable CUDA device")
def test_fallback_copies_the_change_while_the_device_works(monkeypatch):
    """FallbackPlanner's mirror copies are made through CudaPlanner.while_waiting: after the
    call is posted (the loop's seq moved on) and before the wait for it; the mirror ends equal
    to the device's map."""
    from daemon.planning.cuda_planner import CudaPlanner
    from daemon.planning.cuda_resident import ResidentLoop

    blocked, goal, deltas = steps(4)
    inner = CudaPlanner("fast")
    events: list[str] = []
    copies, wait = FallbackPlanner._copies, ResidentLoop.wait

    def copy_change(cells, values):
        events.append("copy")
        return copies(cells, values)

    def loop_wait(loop, io, seq) -> None:
        events.append("wait")
        wait(loop, io, seq)

    monkeypatch.setattr(FallbackPlanner, "_copies", staticmethod(copy_change))
    monkeypatch.setattr(ResidentLoop, "wait", loop_wait)
    planner = FallbackPlanner(inner, cpu_factory=lambda: make_planner("reference"))
    planner.plan(blocked, goal)
    truth = blocked.copy()
    for i, (cells, values, start) in enumerate(deltas[:5]):
        events.clear()
        planner.update_and_path(cells, values, start, full=i == 4)
        truth.reshape(-1)[cells] = values
        # (unsorted cells are posted again after the loop refuses them: a second wait)
        assert events[:2] == ["copy", "wait"] and events.count("copy") == 1, f"step {i}"
        assert inner.while_waiting is None
    assert np.array_equal(planner.mirrored_blocked(), truth)
    assert np.array_equal(planner.mirrored_blocked(), inner.blocked())
