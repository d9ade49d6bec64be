"""The CUDA engine's early relaxation (``HarmonicPlanner.overlap``, its default where the host
searches the whole map): launched before the host's search, kept when nothing was cut off,
undone on the device and run again when something was; the same fields, sweeps and paths
as the steps run in order (GPU machine only: ``pytest -m gpu``)."""

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


def cuda_planner(overlap: bool):
    from daemon.planning.harmonic import HarmonicPlanner
    from daemon.planning.harmonic.cuda import CudaField

    p = HarmonicPlanner(CudaField())
    p.overlap = overlap
    p.plan(door_map(), GOAL)
    return p


def test_cuda_early_relaxation_gives_the_ordered_steps_field_to_the_bit() -> None:
    early, ordered = cuda_planner(True), cuda_planner(False)
    assert np.array_equal(early.field(), ordered.field())
    for cells, value, counts in STEPS:
        a = early.update(cells, np.full(cells.size, value))
        b = ordered.update(cells, np.full(cells.size, value))
        assert a.iterations == b.iterations
        assert np.array_equal(early.field(), ordered.field())
        assert np.array_equal(early.reach.reach, ordered.reach.reach)
        assert (early.residual, early.filled) == (ordered.residual, ordered.filled)
        for start in ((40, 100), (2, 2), (24, 70)):
            assert np.array_equal(early.path(start), ordered.path(start))
        assert (early.overlaps, early.undone) == counts


def test_cuda_undo_gives_back_the_field_and_fixedness_the_launch_found() -> None:
    p = cuda_planner(True)
    engine = p.engine
    w, fixed = engine.w.get(), engine.fixed.get()
    wait = engine.relax_start(20, 1e-9, 10, keep=True)  # past the plan's tolerance: it sweeps
    assert wait()[0] > 0
    assert not np.array_equal(engine.w.get(), w)
    engine.undo()
    assert np.array_equal(engine.w.get(), w) and np.array_equal(engine.fixed.get(), fixed)


def test_cuda_bench_walk_with_the_early_relaxation_is_the_same_walk() -> None:
    # The replanning bench's 400² walk, where the host's whole-map search runs on steps 26, 34
    # and 40 and tries on 42, 53 and 54: the same trace and the same final field.
    from sim.harmonic_bench import _navigator
    from sim.scenarios import make_scenario
    from sim.walk import walk

    scenario = make_scenario("courtyard", 400, 0.4, 0)
    runs = {}
    for overlap in (True, False):
        nav = _navigator(scenario, "harmonic", "cuda")
        nav.route.planner.overlap = overlap
        r = walk(scenario, backend="cuda", mode="harmonic", max_steps=60, navigator=nav)
        runs[overlap] = (r, nav.route.planner)
    (r1, p1), (r0, p0) = runs[True], runs[False]
    assert np.array_equal(r1.changed, r0.changed) and np.array_equal(r1.iterations, r0.iterations)
    assert np.array_equal(p1.field(), p0.field())
    assert p1.overlaps >= 3 and p0.overlaps == p0.undone == 0
    assert p1.reach.full_searches == p0.reach.full_searches
