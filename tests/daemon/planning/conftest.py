"""The planners under test: every backend and variant runs the same tests.

``cpu-fast-repair`` is the fast CPU planner that never cuts over to a full plan, so the
repair itself meets every property test. ``cuda-*`` cases are marked ``gpu`` and skipped
where no CUDA device answers, so the GPU machine runs exactly these tests with
``pytest -m gpu``.
"""

from __future__ import annotations

from collections.abc import Callable

import pytest

from daemon.planning import cuda_available, make_planner
from daemon.planning.cpu.fast import FastCpuPlanner
from daemon.planning.field import FieldPlanner

PLANNERS = [
    pytest.param(("cpu", "fast"), id="cpu-fast"),
    pytest.param(("cpu", "fast-repair"), id="cpu-fast-repair"),
    pytest.param(("cpu", "paper"), id="cpu-paper"),
    pytest.param(("cuda", "fast"), id="cuda-fast", marks=pytest.mark.gpu),
    pytest.param(("cuda", "paper"), id="cuda-paper", marks=pytest.mark.gpu),
]


@pytest.fixture(params=PLANNERS)
def make(request) -> Callable[..., FieldPlanner]:
    """A factory of fresh planners of one backend and variant: ``make()`` EDS, ``make("dss")``."""
    backend, variant = request.param
    if backend == "cuda" and not cuda_available():
        pytest.skip("no usable CUDA device")

    def factory(name: str = "eds") -> FieldPlanner:
        if variant == "fast-repair":  # small test maps would mostly cut over to a full plan
            return FastCpuPlanner(dss=name == "dss", cut_over=1e6)
        if backend == "cuda":  # the kernels themselves, whatever the grid (no small-grid rule)
            from daemon.planning.cuda.planner import CudaPlanner

            return CudaPlanner(variant, dss=name == "dss")
        planner = make_planner(name, backend, variant)
        assert isinstance(planner, FieldPlanner)
        return planner

    return factory
