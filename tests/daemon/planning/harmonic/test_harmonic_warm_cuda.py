"""After the daemon's warm-up on the device, the bench's 400² walk compiles or loads no numba
function (GPU machine only: ``pytest -m gpu``). The CPU engine's walk is checked in
``tests/daemon/planning/test_warm.py``; this is the CuPy engine's, whose host code (the queue's
packing, the descent along Idx, the host's fill) the CPU walk never runs."""

from __future__ import annotations

import pytest

from daemon.navigation.warm import warm_up
from daemon.planning import cuda_available
from sim.harmonic_bench import _navigator
from sim.numba_loads import numba_signatures
from sim.scenarios import make_scenario
from sim.walk import walk

pytestmark = [
    pytest.mark.gpu,
    pytest.mark.skipif(not cuda_available(), reason="no usable CUDA device"),
    pytest.mark.timeout(120),
]


def test_after_the_warm_up_the_cuda_bench_walk_loads_nothing() -> None:
    # The replanning bench's 400² walk: its whole-map reach searches are the host's (steps 26,
    # 34 and 40), its cut-off tries too; a first use there would cost a step ~2–70 ms.
    scenario = make_scenario("courtyard", 400, 0.4, 0)
    assert warm_up("harmonic", "cuda") > 0
    before = numba_signatures()
    nav = _navigator(scenario, "harmonic", "cuda")
    r = walk(scenario, backend="cuda", mode="harmonic", max_steps=60, navigator=nav)
    after = numba_signatures()
    new = {k: after[k] - before.get(k, 0) for k in after if after[k] != before.get(k, 0)}
    assert new == {}, f"compiled or loaded during the walk, not in the warm-up: {new}"
    reach = nav.route.planner.reach
    assert r.steps == 60 and reach.full_searches + reach.cut_searches > 0
