"""A step's fill launched right behind its sweeps (``HarmonicPlanner.fill_behind``, the engine's
``fill_start``) against the fill after the sweeps' wait: the same field, sweeps, fills and
paths. Here on the CPU engine, whose ``fill_start`` fills at once (its relaxation has run
already), so this checks the planner's two paths (the step's, the early relaxation's); the
CUDA engine's launch, gated on the device, is checked in ``test_harmonic_fill_behind_cuda.py``.
"""

from __future__ import annotations

import numpy as np
import pytest

from daemon.planning.harmonic import HarmonicPlanner
from daemon.planning.harmonic import relax as rx
from daemon.planning.harmonic.cpu import CpuField

from .test_harmonic_overlap import DOORS, GOAL, STEPS, WALL, W, door_map

pytestmark = pytest.mark.timeout(60)


def planner(overlap: bool, behind: bool, sweeps: int | None) -> HarmonicPlanner:
    p = HarmonicPlanner(CpuField())
    p.overlap, p.fill_behind = overlap, behind
    p.plan(door_map(), GOAL)
    if sweeps is not None:
        p.step_sweeps, p.step_cap = sweeps, sweeps
    return p


@pytest.mark.parametrize("sweeps", [None, 5])
@pytest.mark.parametrize("overlap", [True, False])
def test_the_fill_behind_the_sweeps_is_the_fill_after_them(overlap: bool, sweeps) -> None:
    behind, after = planner(overlap, True, sweeps), planner(overlap, False, sweeps)
    filled = []
    for cells, value, _ in STEPS:
        a = behind.update(cells, np.full(cells.size, value))
        b = after.update(cells, np.full(cells.size, value))
        assert (a.iterations, a.cells_touched) == (b.iterations, b.cells_touched)
        assert np.array_equal(behind.field(), after.field())
        assert np.array_equal(behind.engine.idx, after.engine.idx)
        assert (behind.residual, behind.filled, behind.fills, behind.settled) == (
            after.residual,
            after.filled,
            after.fills,
            after.settled,
        )
        assert (behind.overlaps, behind.undone) == (after.overlaps, after.undone)
        for start in ((40, 100), (2, 2), (24, 70)):
            assert np.array_equal(behind.path(start), after.path(start))
        filled.append(behind.filled)
    # Steps that left pits and steps that left none, both through each path.
    assert max(filled) > 100 and min(filled) == 0
    assert behind.overlaps == (1 if overlap else 0)


def test_the_cpu_engines_fill_start_is_its_fill() -> None:
    # Door A closed on the engine alone (padded cells), five sweeps: pits are left to fill.
    a, b = planner(False, True, None), planner(False, True, None)
    door = np.array([(r + 1) * (W + 2) + WALL + 1 for r in DOORS[0]], dtype=np.int64)
    for p in (a, b):
        p.engine.set(door, rx.BLOCKED_W, True)
        p.engine.relax_start(5, 1e-4, 5)()
    assert a.engine.fill_start()() == b.engine.fill() != (0, 0)
    assert np.array_equal(a.engine.w, b.engine.w)
