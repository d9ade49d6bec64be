"""The CuPy engine against the numba one: the same contract, fields within a stated
tolerance, warm replans equal to cold plans (GPU machine only: ``pytest -m gpu``)."""

from __future__ import annotations

import numpy as np
import pytest

from daemon.planning import cuda_available, make_planner

pytestmark = [
    pytest.mark.gpu,
    pytest.mark.skipif(not cuda_available(), reason="no usable CUDA device"),
    pytest.mark.timeout(120),
]

GPU_TOL = 1e-2
"""CPU (float64) and GPU (float32) fields, each stopped at residual 1e-4, agree on ``w``
within this (log units: 1 % of ``1 − u``); float32 rounds ``w`` ~ 300 to 3e-5."""


def cuda_planner(kernel: str):
    """The cuda planner sweeping with ``kernel``: four-colour SOR (``rb``), or the paper's
    Jacobi sweeps from the median-range start."""
    from daemon.planning.harmonic import HarmonicPlanner
    from daemon.planning.harmonic.cuda import CudaField

    init = "paper" if kernel == "jacobi" else "distance"
    return HarmonicPlanner(CudaField(order=kernel), init=init)


@pytest.mark.parametrize("seed", range(6))
@pytest.mark.parametrize("kernel", ["rb", "jacobi"])
def test_cuda_and_cpu_fields_agree_and_descend(maps, seed, kernel):
    rng = np.random.default_rng(seed)
    h, w = int(rng.integers(10, 60)), int(rng.integers(10, 60))
    blocked = maps.random_map(rng, h, w, 0.25)
    goal = (int(rng.integers(0, h)), int(rng.integers(0, w)))
    blocked[goal] = False
    variant = "paper" if kernel == "jacobi" else "fast"
    cpu, gpu = make_planner("harmonic", "cpu", variant), cuda_planner(kernel)
    cpu.plan(blocked, goal)
    gpu.plan(blocked, goal)
    reach = maps.reachable(blocked, goal) & ~blocked
    assert gpu.residual < 1e-4
    assert np.abs(cpu.field()[reach] - gpu.field()[reach]).max() < GPU_TOL
    maps.descents_hold(gpu, blocked, maps.reachable(blocked, goal), steps=True)


def test_cuda_warm_replans_equal_cold_plans(maps):
    rng = np.random.default_rng(11)
    blocked = maps.random_map(rng, 80, 80, 0.1)
    goal = (3, 3)
    blocked[goal] = False
    warm = cuda_planner("rb")
    warm.plan(blocked, goal)
    for _ in range(8):
        r, c = int(rng.integers(5, 75)), int(rng.integers(5, 75))
        cells = (np.arange(r, r + 5)[:, None] * 80 + np.arange(c, c + 5)[None, :]).ravel()
        values = rng.random(cells.size) < 0.7
        values[cells == 3 * 80 + 3] = False
        warm.update(cells, values)
        blocked.reshape(-1)[cells] = values
        assert warm.settled  # the step's stop: converged, or no pit
        maps.descents_hold(warm, blocked, maps.reachable(blocked, goal), steps=True)
    warm.converge()
    assert warm.residual < 1e-4
    cold = cuda_planner("rb")
    cold.plan(blocked, goal)
    reach = maps.reachable(blocked, goal) & ~blocked
    assert np.abs(warm.field()[reach] - cold.field()[reach]).max() < GPU_TOL
    maps.descents_hold(warm, blocked, maps.reachable(blocked, goal), steps=True)


def test_cuda_has_no_plateau_on_the_serpentine(maps):
    blocked, start, goal = maps.serpentine(64)
    gpu = cuda_planner("rb")
    gpu.plan(blocked, goal)
    assert gpu.field()[start] > 40
    assert tuple(gpu.path(start)[-1]) == goal


@pytest.mark.parametrize("seed", range(3))
def test_cuda_steps_filled_are_pit_free_and_converge_to_the_cold_field(maps, seed):
    # One sweep a step, then the fill (fill.py) on the host from the kernel's pit list: the
    # device's w and the host's Idx must both come out without a pit.
    from daemon.planning.harmonic import relax as rx

    rng = np.random.default_rng(100 + seed)
    blocked = maps.random_map(rng, 50, 50, 0.15)
    goal = (int(rng.integers(0, 50)), int(rng.integers(0, 50)))
    blocked[goal] = False
    warm = cuda_planner("rb")
    warm.plan(blocked, goal)
    warm.step_sweeps, warm.step_cap = 1, 1
    engine = warm.engine
    fills = 0
    for _ in range(6):
        r, c = int(rng.integers(2, 45)), int(rng.integers(2, 45))
        cells = (np.arange(r, r + 5)[:, None] * 50 + np.arange(c, c + 5)[None, :]).ravel()
        values = rng.random(cells.size) < 0.7
        values[cells == goal[0] * 50 + goal[1]] = False
        stats = warm.update(cells, values)
        blocked.reshape(-1)[cells] = values
        fills += warm.filled > 0
        assert stats.iterations <= 1 and warm.settled
        field = engine.w.get()
        assert not rx.has_pit(field, engine.fixed_host.astype(bool), engine.width)
        host_idx = engine.idx_view.copy()
        engine.relax(0, 1e-4, 0)  # no sweep: the kernel's Idx of the same field
        assert (engine.idx_view == host_idx).all()
        maps.descents_hold(warm, blocked, maps.reachable(blocked, goal), steps=True)
    assert fills > 0
    warm.converge()
    assert warm.residual < 1e-4
    cold = cuda_planner("rb")
    cold.plan(blocked, goal)
    reach = maps.reachable(blocked, goal) & ~blocked
    assert np.abs(warm.field()[reach] - cold.field()[reach]).max() < GPU_TOL


def _walled_with_two_doors(overlap: bool = True, behind: bool = True):
    """A 40² room cut by a wall with two doors, planned on the GPU with a 5-sweep step; the
    far door's cells, closing which leaves a basin behind the wall to fill. Closing it takes
    the whole-map search (the door's two sides join only through the other door), so with
    ``overlap`` the step's sweeps and fill start before it (``HarmonicPlanner._start_early``).
    ``behind``: the planner's ``fill_behind`` (False: ``engine.fill`` after the sweeps' wait)."""
    blocked = np.zeros((40, 40), dtype=bool)
    blocked[20, :] = True
    blocked[20, 2:4] = blocked[20, 34:38] = False
    door = 20 * 40 + np.arange(34, 38)
    gpu = cuda_planner("rb")
    gpu.overlap, gpu.fill_behind = overlap, behind
    gpu.plan(blocked, (2, 36))
    gpu.step_sweeps, gpu.step_cap = 5, 5
    return blocked, door, gpu


def test_cuda_fills_the_basin_a_wall_leaves(maps):
    blocked, door, gpu = _walled_with_two_doors()
    stats = gpu.update(door, True)
    blocked.reshape(-1)[door] = True
    assert stats.iterations <= 5 and gpu.filled > 100 and gpu.settled
    maps.descents_hold(gpu, blocked, maps.reachable(blocked, (2, 36)), steps=True)


def test_cuda_changes_queued_for_the_launch_match_the_cpu_engine(maps):
    # ``set`` queues a step's changes for the relaxation's own launch (``harmonic.cu``'s
    # ``apply_changes``): blocked cells, newly reachable ones and the goal freed again (in
    # the same step as a cell beside it) must come out as the CPU engine sets them.
    from daemon.planning.harmonic import relax as rx

    blocked = np.zeros((30, 30), dtype=bool)
    goal = (5, 5)
    cpu, gpu = make_planner("harmonic", "cpu"), cuda_planner("rb")
    for planner in (cpu, gpu):
        planner.plan(blocked, goal)
    wall = 15 * 30 + np.arange(0, 28)
    steps = [
        (wall, True),
        (np.array([5 * 30 + 5]), True),
        (np.array([5 * 30 + 5, 5 * 30 + 6, 15 * 30 + 3]), np.array([False, True, False])),
    ]
    for cells, values in steps:
        for planner in (cpu, gpu):
            planner.update(cells, values)
            planner.converge()
        blocked.reshape(-1)[cells] = values
        reach = maps.reachable(blocked, goal) & ~blocked
        f_cpu, f_gpu = cpu.field(), gpu.field()
        assert ((f_gpu >= rx.BLOCKED_W / 2) == (f_cpu >= rx.BLOCKED_W / 2)).all()
        if reach.any():  # not while the goal itself is blocked
            assert np.abs(f_cpu[reach] - f_gpu[reach]).max() < GPU_TOL
        engine = gpu.engine
        assert (engine.fixed.get() == engine.fixed_host).all()
        maps.descents_hold(gpu, blocked, maps.reachable(blocked, goal), steps=True)
    assert gpu.field()[goal] == 0.0
    # Queued and read back without a relaxation: ``field`` applies them first.
    gpu.engine.set(np.array([gpu._flat((20, 20))]), rx.BLOCKED_W, True)
    assert gpu.field()[20, 20] >= rx.BLOCKED_W / 2


@pytest.mark.parametrize("passes", [None, 1])
def test_cuda_fill_is_the_cpu_fill_and_falls_back_to_the_host(maps, monkeypatch, passes):
    # The device's passes (``harmonic_fill``) and the host's heap (``fill.flood``) reach the
    # same fixed point from the same field; capped at one pass, the cells the passes did not
    # reach are left to the host's flood, and the step still ends without a pit.
    from daemon.planning.harmonic import cuda as hc
    from daemon.planning.harmonic import relax as rx
    from daemon.planning.harmonic.cpu import CpuField

    if passes is not None:
        monkeypatch.setattr(hc, "FILL_PASSES", passes)
    # In order: the field between the sweeps and the fill is read here, which a fill launched
    # behind the sweeps never leaves on the host; that one is checked against this one below
    # and in ``test_harmonic_fill_behind_cuda.py``.
    blocked, door, gpu = _walled_with_two_doors(overlap=False, behind=False)
    engine, before = gpu.engine, {}
    device_fill = engine.fill

    def fill(eps):
        engine._flush()
        before["w"], before["fixed"] = engine.w.get(), engine.fixed_host.astype(bool)
        return device_fill(eps)

    monkeypatch.setattr(engine, "fill", fill)
    gpu.update(door, True)
    blocked.reshape(-1)[door] = True
    assert gpu.filled > 100 and gpu.settled
    after = engine.w.get()
    assert not rx.has_pit(after, before["fixed"], engine.width)
    maps.descents_hold(gpu, blocked, maps.reachable(blocked, (2, 36)), steps=True)
    if passes is None:
        assert 1 < engine.fill_passes < hc.FILL_PASSES
        host = CpuField()
        host.load(before["fixed"], before["w"].astype(np.float64), engine.width, engine.goal)
        n_basin, left = host.fill()
        assert left == 0 and n_basin == gpu.filled
        free = host.w < rx.BLOCKED_W
        assert np.abs(host.w[free] - after[free]).max() < GPU_TOL
    else:
        assert engine.fill_passes == 1


@pytest.mark.parametrize("passes", [None, 1])
def test_cuda_fill_behind_the_early_relaxation_is_the_fill_after_it(monkeypatch, passes):
    # ``CudaField.fill_start``: the step's fill launched behind its early relaxation (or the
    # ordered step's sweeps), before the host knows whether the sweeps left a pit, gives the
    # field and the counts of the fill run after the wait; capped at one pass, all leave the
    # rest to the host's flood.
    from daemon.planning.harmonic import cuda as hc

    if passes is not None:
        monkeypatch.setattr(hc, "FILL_PASSES", passes)
    _, door, early = _walled_with_two_doors(overlap=True)
    _, _, behind = _walled_with_two_doors(overlap=False)
    _, _, after = _walled_with_two_doors(overlap=False, behind=False)
    a, b, c = (p.update(door, True) for p in (early, behind, after))
    assert (early.overlaps, early.undone, behind.overlaps, after.overlaps) == (1, 0, 0, 0)
    for p, s in ((early, a), (behind, b)):
        assert s.iterations == c.iterations and p.residual == after.residual
        assert p.filled == after.filled > 100 and p.settled and after.settled
        assert np.array_equal(p.field(), after.field())
        assert np.array_equal(p.engine.idx_view, after.engine.idx_view)
        assert p.engine.fill_passes == after.engine.fill_passes
        assert np.array_equal(p.path((39, 2)), after.path((39, 2)))
    if passes is not None:
        assert after.engine.fill_passes == 1


def _fixed_point_f32(w: np.ndarray, cells: np.ndarray, width: int, eps: float) -> np.ndarray:
    """The fill's fixed point W = max(w, min neighbour W + eps) on ``cells``, by lockstep
    passes over them in float32 (the device's arithmetic, one pass at a time): the reference
    the tiled passes must reach to the last bit."""
    from daemon.planning.harmonic import relax as rx

    big = np.float32(rx.BLOCKED_W)
    out = w.astype(np.float32)
    lift = out[cells].copy()
    out[cells] = big
    offs = np.array([(d // 3 - 1) * width + d % 3 - 1 for d in range(9) if d != 4])
    around = cells[:, None] + offs[None, :]
    eps32 = np.float32(eps)
    while True:
        m = out[around].min(axis=1)
        valued = m < big
        step = np.full_like(m, eps32)
        v = m + step
        while (short := valued & (v <= m)).any():  # float32 rounds m + eps back to m
            step[short] *= 2
            v[short] = m[short] + step[short]
        v = np.where((lift < big) & (lift > v), lift, v)
        now = out[cells]
        new = np.where(valued, np.minimum(now, v), now)
        if (new == now).all():
            return out
        out[cells] = new


@pytest.mark.parametrize("seed", range(3))
def test_cuda_tiled_fill_is_the_fixed_point_to_the_bit(maps, monkeypatch, seed):
    # ``harmonic_fill`` finds the basins by pointer jumping along Idx and iterates tiles in
    # shared memory between grid barriers: the same basins as the host's search, and the same
    # fixed point the passes cell by cell reach, on basins across many tiles (a wall across a
    # 130² map, its door nearest the goal closed, then random blocks).
    from daemon.planning.harmonic import fill as fl
    from daemon.planning.harmonic import relax as rx

    rng = np.random.default_rng(200 + seed)
    side = 130
    blocked = maps.random_map(rng, side, side, 0.06)
    row = int(rng.integers(50, 80))
    blocked[row, :] = True
    doors = [int(rng.integers(2, 40)), int(rng.integers(90, 126))]
    for door in doors:
        blocked[row, door : door + 3] = False
    goal = (int(rng.integers(2, row - 10)), int(rng.integers(2, 40)))
    blocked[goal] = False
    gpu = cuda_planner("rb")
    gpu.fill_behind = False  # the wrapper below reads the field between the sweeps and the fill
    gpu.plan(blocked, goal)
    gpu.step_sweeps, gpu.step_cap = 1, 1
    engine, seen = gpu.engine, []
    device_fill = engine.fill

    def fill(eps):
        engine._flush()
        if engine.pit_count:
            size = engine.idx_view.size
            cells = np.empty(size, dtype=np.int64)
            n = fl.basins(engine.idx_view, engine.fixed_host, engine.width, engine._pits(),
                          np.zeros(size, dtype=np.int8), cells, False)[0]  # fmt: skip
            want = _fixed_point_f32(engine.w.get(), cells[:n], engine.width, eps)
        out = device_fill(eps)
        if out[0]:
            assert out[0] == n  # the device's basins (pointer jumping) are the host's
            assert engine.pit_count == 0  # the device filled it all: no host flood after
            assert np.array_equal(engine.w.get(), want)
            rows, cols = np.divmod(cells[:n], engine.width)
            seen.append((len(np.unique(rows // 32 * 1000 + cols // 32)), engine.fill_passes))
        return out

    monkeypatch.setattr(engine, "fill", fill)
    door = row * side + doors[0] + np.arange(3)
    steps = [(door, np.ones(3, dtype=bool))]
    for _ in range(4):
        r, c = int(rng.integers(2, side - 9)), int(rng.integers(2, side - 9))
        cells = (np.arange(r, r + 7)[:, None] * side + np.arange(c, c + 7)[None, :]).ravel()
        values = rng.random(cells.size) < 0.6
        values[cells == goal[0] * side + goal[1]] = False
        steps.append((cells, values))
    for cells, values in steps:
        gpu.update(cells, values)
        blocked.reshape(-1)[cells] = values
        assert gpu.settled
        assert not rx.has_pit(engine.w.get(), engine.fixed_host.astype(bool), engine.width)
        maps.descents_hold(gpu, blocked, maps.reachable(blocked, goal), steps=True)
    assert max(tiles for tiles, _ in seen) >= 4 and all(passes >= 2 for _, passes in seen)


@pytest.mark.parametrize("seed", range(4))
def test_cuda_reach_search_is_the_host_search(maps, seed):
    # ``harmonic_reach`` (tiles grown from the goal) against the host's breadth-first search
    # of the same padded map, the goal blocked once: the cells whose reach changed.
    rng = np.random.default_rng(300 + seed)
    h, w = int(rng.integers(60, 200)), int(rng.integers(60, 200))
    blocked = maps.random_map(rng, h, w, 0.3 + 0.05 * seed)
    goal = (int(rng.integers(0, h)), int(rng.integers(0, w)))
    blocked[goal] = seed == 3
    gpu = cuda_planner("rb")
    gpu.plan(np.zeros((h, w), dtype=bool), (0, 0))
    flat = np.ones((h + 2, w + 2), dtype=np.bool_)
    flat[1:-1, 1:-1] = blocked
    flat = flat.reshape(-1)
    g = (goal[0] + 1) * (w + 2) + goal[1] + 1
    before = rng.random(flat.size) < 0.5
    fresh = maps.flat_reachable(flat, g, w + 2)
    count = int(fresh.sum())
    got = gpu.engine.reach_search(flat, before, g)
    assert np.array_equal(np.sort(got), np.flatnonzero(fresh != before))
    assert (count > 0) == (seed != 3) and gpu.engine.reach_passes >= 1
