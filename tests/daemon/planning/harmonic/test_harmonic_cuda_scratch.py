"""The CuPy engine's host scratch is mapped at ``load`` (a plan), not by the first replanning
step (GPU machine only: ``pytest -m gpu``)."""

from __future__ import annotations

import resource

import numpy as np
import pytest

from daemon.planning import cuda_available

pytestmark = [
    pytest.mark.gpu,
    pytest.mark.skipif(not cuda_available(), reason="no usable CUDA device"),
    pytest.mark.timeout(120),
]


def _planned(side: int):
    from daemon.planning.harmonic import HarmonicPlanner
    from daemon.planning.harmonic.cuda import CudaField

    blocked = np.zeros((side, side), dtype=bool)
    blocked[side // 4 : side // 2, 10 : side - 10] = True
    planner = HarmonicPlanner(CudaField())
    planner.plan(blocked, (side - 5, side // 2))
    return planner, blocked


def _faults() -> int:
    return resource.getrusage(resource.RUSAGE_SELF).ru_minflt


def test_the_host_scratch_is_mapped_by_the_plan():
    planner, _ = _planned(512)
    f = planner.engine
    scratch = (f.vals, f.mark, f.cells, f.queued, f.cells_host, f.vals_host, f.masks_host,
               f.idx_view, f.buf[: 4 * (f.height + f.width)])  # fmt: skip
    before = _faults()
    for a in scratch:  # what a first large step may write: every page of each
        a[::512] = a[::512]
    # 514² cells: left to their first write, vals, cells and mark alone are ~840 pages.
    assert _faults() - before < 64


def test_mapping_the_scratch_leaves_the_field_and_the_paths_as_they_were(monkeypatch):
    from daemon.planning.harmonic.cuda import CudaField

    planner, blocked = _planned(96)
    monkeypatch.setattr(CudaField, "_map_host", lambda self: None)
    bare, _ = _planned(96)
    np.testing.assert_array_equal(planner.field(), bare.field())
    goal, start = 91 * 96 + 48, 2 * 96 + 3
    changed = np.setdiff1d(np.flatnonzero(~blocked)[::101], [goal, start])
    blocked.reshape(-1)[changed] = True
    for p in (planner, bare):
        p.update(changed.astype(np.int64), np.ones(changed.size, dtype=bool))
    np.testing.assert_array_equal(planner.field(), bare.field())
    np.testing.assert_array_equal(planner.path((2, 3)), bare.path((2, 3)))
    assert len(planner.path((2, 3))) > 0
