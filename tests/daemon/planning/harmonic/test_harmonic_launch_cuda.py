"""The harmonic engine's kernels launched through the driver with their arguments kept in place
(``launch.Launch``): the same launches as CuPy's own call of the same kernel, and each
launch's changed arguments reach the kernel (GPU machine only: ``pytest -m gpu``)."""

from __future__ import annotations

import numpy as np
import pytest

from daemon.planning import cuda_available

pytestmark = [
    pytest.mark.gpu,
    pytest.mark.skipif(not cuda_available(), reason="no usable CUDA device"),
    pytest.mark.timeout(120),
]


def _loaded(seed: int):
    """A planned 96 x 130 random map's engine (a goal, 25 % obstacles)."""
    from daemon.planning.harmonic import HarmonicPlanner
    from daemon.planning.harmonic.cuda import CudaField

    rng = np.random.default_rng(seed)
    blocked = rng.random((96, 130)) < 0.25
    blocked[48, 65] = False
    p = HarmonicPlanner(CudaField())
    p.plan(blocked, (48, 65))
    return p, rng


def _cupy_relax(e, sweeps: int, tol: float, budget: int) -> tuple[int, float, bool]:
    """``relax`` as the engine launched it before ``Launch``: CuPy's ``RawKernel`` call."""
    import cupy as cp

    from daemon.planning.harmonic.cuda import THREADS
    from daemon.planning.harmonic.launch import H2D, copy_async

    n = e.n_queued
    copy_async(e.changes.data.ptr, e.queued.ctypes.data, 4 * n, H2D)
    e.kernel((e.blocks,), (THREADS,),
             (e.w, e.fixed, e.prev, np.int32(e.height), np.int32(e.width), np.int32(e.jacobi),
              e.omega, np.int32(sweeps), np.int32(e.check_every), np.float32(tol), e.worst,
              e.result, e.idx, np.int32(budget), e.pits, e.pit_list, e.changes, np.int32(n),
              np.int32(e.late)))  # fmt: skip
    e.n_queued, e.late = 0, False
    cp.cuda.get_current_stream().synchronize()
    return e._relaxed()


@pytest.mark.parametrize("seed", [0, 1])
def test_launches_kept_in_place_are_cupys_launches_to_the_bit(seed: int) -> None:
    ours, rng = _loaded(seed)
    theirs, _ = _loaded(seed)
    from daemon.planning.harmonic import relax as rx

    cells = np.flatnonzero(rng.random(96 * 130) < 0.01).astype(np.int64)
    cells = cells[cells != 48 * 130 + 65]
    flat = (cells // 130 + 1) * 132 + cells % 130 + 1
    for p in (ours, theirs):
        # The same queued changes (newly blocked cells) for both launches.
        p.engine.set(flat, rx.BLOCKED_W, True)
    p_ours = ours.engine.relax(20, 1e-9, 10)
    p_theirs = _cupy_relax(theirs.engine, 20, 1e-9, 10)
    assert p_ours == p_theirs
    assert np.array_equal(ours.engine.w.get(), theirs.engine.w.get())
    assert np.array_equal(ours.engine.idx.get(), theirs.engine.idx.get())
    assert ours.engine.fill() == theirs.engine.fill()
    assert np.array_equal(ours.engine.w.get(), theirs.engine.w.get())


def test_each_launch_takes_its_own_sweeps_tolerance_and_omega() -> None:
    p, _ = _loaded(2)
    e = p.engine
    assert e.relax(3, 0.0, 3)[0] == 3
    assert e.relax(7, 0.0, 7)[0] == 7
    w = (e.w.get() * 1.05).astype(e.dtype)  # off the fixed point: each omega moves it
    e.w.set(w)
    e.omega = e.dtype.type(1.0)
    one = e.relax(1, 0.0, 1)
    w_one = e.w.get()
    e.w.set(w)
    e.omega = e.dtype.type(1.5)
    assert e.relax(1, 0.0, 1)[0] == one[0] == 1
    assert not np.array_equal(e.w.get(), w_one)  # the other omega moved the field otherwise
    assert e.relax(500, 1e30, 500)[0] == e.check_every  # stops at its first check
