"""The CUDA engine's fill launched right behind a step's sweeps (``CudaField.fill_start``,
``HarmonicPlanner.fill_behind``), gated on the device by the sweeps' own pit count, against
the fill launched after the sweeps' wait: the same field, Idx, sweeps and fill counts to the
bit, on steps with pits and without, on a relaxation that does not settle, and where the
device's passes leave cells to the host's flood (GPU machine only: ``pytest -m gpu``)."""

from __future__ import annotations

import numpy as np
import pytest

from daemon.planning import cuda_available

from .test_harmonic_overlap import GOAL, STEPS, door_map

pytestmark = [
    pytest.mark.gpu,
    pytest.mark.skipif(not cuda_available(), reason="no usable CUDA device"),
    pytest.mark.timeout(120),
]


def cuda_planner(behind: bool, overlap: bool = False, init: str = "distance"):
    from daemon.planning.harmonic import HarmonicPlanner
    from daemon.planning.harmonic.cuda import CudaField

    p = HarmonicPlanner(CudaField(), init=init)
    p.overlap, p.fill_behind = overlap, behind
    return p


def recorded(p) -> list:
    """What each ``update`` of ``p`` leaves: its sweeps, the residual, the fill's cells and
    passes, the step's settled flag, the relaxation's own settled flag and pit count (before
    the fill), and Idx. The relaxation's result is read by wrapping the engine's wait."""
    log, seen = [], {}
    engine, update, start = p.engine, p.update, p.engine.relax_start

    def relax_start(*args, **kwargs):
        wait = start(*args, **kwargs)

        def waited():
            out = wait()
            seen["relaxed"] = (out[2], engine.pit_count)
            return out

        return waited

    def updated(cells, values):
        seen.clear()
        s = update(cells, values)
        log.append((s.iterations, p.residual, p.filled, engine.fill_passes, p.settled,
                    seen.get("relaxed"), engine.idx_view.copy()))  # fmt: skip
        return s

    engine.relax_start, p.update = relax_start, updated
    return log


def same(a: list, b: list) -> None:
    assert len(a) == len(b)
    for x, y in zip(a, b, strict=True):
        assert x[:6] == y[:6]
        assert np.array_equal(x[6], y[6])


@pytest.mark.parametrize("passes", [None, 1])
@pytest.mark.parametrize("overlap", [True, False])
def test_cuda_fill_behind_is_the_fill_after_the_wait_on_the_door_map(monkeypatch, overlap,
                                                                      passes) -> None:  # fmt: skip
    # The wall with two doors (``test_harmonic_overlap.py``'s sequence: early starts that
    # stand and that are undone when ``overlap``), 5-sweep steps: fills of ~500 and ~2 500
    # cells and steps without a pit. Capped at one pass, the fills leave cells to the host.
    if passes is not None:
        from daemon.planning.harmonic import cuda as hc

        monkeypatch.setattr(hc, "FILL_PASSES", passes)
    runs = {}
    for behind in (True, False):
        p = cuda_planner(behind, overlap)
        p.plan(door_map(), GOAL)
        p.step_sweeps, p.step_cap = 5, 5
        log = recorded(p)
        for cells, value, _ in STEPS:
            p.update(cells, np.full(cells.size, value))
        runs[behind] = (p, log)
    (p1, a), (p0, b) = runs[True], runs[False]
    same(a, b)
    assert np.array_equal(p1.field(), p0.field())
    assert (p1.fills, p1.overlaps, p1.undone) == (p0.fills, p0.overlaps, p0.undone)
    for start in ((40, 100), (2, 2), (24, 70)):
        assert np.array_equal(p1.path(start), p0.path(start))
    filled = [x[2] for x in a]
    assert max(filled) > 100 and min(filled) == 0 and all(x[4] for x in a)
    if passes is not None:
        assert all(x[3] == 1 for x in a if x[2])  # every fill left cells to the host's flood
    if overlap:
        assert p1.overlaps >= 1 and p1.undone >= 1


def test_cuda_fill_behind_a_relaxation_that_does_not_settle(monkeypatch) -> None:
    # A plan from the paper's median-range field cut short (its budget's quarter at the
    # engine's omega, the rest at omega 1, both unsettled: flat, so full of pits), then
    # one-sweep steps of random blocks: relaxations that end with pits and unsettled, each
    # filled behind its sweeps, as the fill after the wait fills them.
    from daemon.planning.harmonic import planner as hp

    monkeypatch.setattr(hp, "COLD_SWEEPS", 8)
    rng = np.random.default_rng(7)
    blocked = rng.random((60, 70)) < 0.15
    blocked[5, 5] = False
    steps = []
    for _ in range(6):
        r, c = int(rng.integers(2, 53)), int(rng.integers(2, 63))
        cells = (np.arange(r, r + 5)[:, None] * 70 + np.arange(c, c + 5)[None, :]).ravel()
        values = rng.random(cells.size) < 0.7
        values[cells == 5 * 70 + 5] = False
        steps.append((cells, values))
    runs = {}
    for behind in (True, False):
        p = cuda_planner(behind, init="paper")
        p.plan(blocked, (5, 5))
        assert not p.settled
        p.step_sweeps, p.step_cap = 1, 1
        log = recorded(p)
        for cells, values in steps:
            p.update(cells, values)
        runs[behind] = (p, log)
    (p1, a), (p0, b) = runs[True], runs[False]
    same(a, b)
    assert np.array_equal(p1.field(), p0.field())
    assert any(not x[5][0] and x[5][1] > 0 for x in a)  # a relaxation unsettled, with pits
    assert all(x[4] for x in a)  # and every step still ends without a pit


def test_cuda_gate_keeps_the_fill_out_when_the_sweeps_leave_no_pit() -> None:
    # The gated launch writes nothing: the fill's result words keep what was there before.
    from daemon.planning.harmonic import relax as rx

    p = cuda_planner(True)
    p.plan(door_map(), GOAL)
    e = p.engine
    e.result[4:].fill(-7)
    wait = e.relax_start(20, p.tol, 10)
    filled = e.fill_start()
    assert wait()[2] and e.pit_count == 0
    assert filled() == (0, 0) and e.fill_passes == 0
    assert (e.result_host[4:] == -7).all()
    # Door A closed, one sweep: pits, and the launch behind them fills and writes its words.
    door = np.array([(r + 1) * 122 + 61 for r in range(6, 9)], dtype=np.int64)
    e.set(door, rx.BLOCKED_W, True)
    wait = e.relax_start(1, p.tol, 1)
    filled = e.fill_start()
    wait()
    assert e.pit_count > 0
    n_basin, left = filled()
    assert n_basin > 100 and left == 0 and e.fill_passes >= 1
    assert (e.result_host[4:] != -7).any()


def test_cuda_bench_walk_with_the_fill_behind_is_the_same_walk() -> None:
    # The replanning bench's 400² walk, 60 steps (fills of 5–28 k cells, steps without): the
    # same trace, every step's sweeps, fill and Idx, and the same final field.
    from sim.harmonic_bench import _navigator
    from sim.scenarios import make_scenario
    from sim.walk import walk

    scenario = make_scenario("courtyard", 400, 0.4, 0)
    runs = {}
    for behind in (True, False):
        nav = _navigator(scenario, "harmonic", "cuda")
        p = nav.route.planner
        p.fill_behind = behind
        log = recorded(p)
        r = walk(scenario, backend="cuda", mode="harmonic", max_steps=60, navigator=nav)
        runs[behind] = (r, p, log)
    (r1, p1, a), (r0, p0, b) = runs[True], runs[False]
    assert np.array_equal(r1.changed, r0.changed) and np.array_equal(r1.iterations, r0.iterations)
    same(a, b)
    assert np.array_equal(p1.field(), p0.field())
    assert p1.fills == p0.fills > 3 and min(x[2] for x in a) == 0
