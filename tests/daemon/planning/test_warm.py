"""The warm-up runs every compiled entry point a walk uses: after it, a walk compiles nothing."""

from __future__ import annotations

import logging

import pytest

from daemon.navigation.warm import warm_up
from daemon.planning.registry import PLANNERS
from sim.numba_loads import numba_signatures
from sim.scenarios import make_scenario
from sim.walk import walk

pytestmark = pytest.mark.timeout(120)


# The courtyard's first 60 steps; and a whole walk of 100² streets, whose step 1 gives the
# planner its changes without a path read (``update``: a cached load of 5-10 ms in that step
# until the warm-up ran it, on the cuda backend's small grids too).
WALKS = [("courtyard", 50, 0.4, 60), ("streets", 100, 0.2, None)]


@pytest.mark.parametrize("name, grid, unknown, steps", WALKS)
@pytest.mark.parametrize("planner", list(PLANNERS))
def test_after_the_warm_up_a_walk_compiles_nothing(
    planner: str, name: str, grid: int, unknown: float, steps: int | None
) -> None:
    scenario = make_scenario(name, grid, unknown, 0)
    assert warm_up(planner, "cpu") > 0
    before = numba_signatures()
    walk(scenario, mode=planner, max_steps=steps)
    after = numba_signatures()
    new = {k: after[k] - before.get(k, 0) for k in after if after[k] != before.get(k, 0)}
    assert new == {}, f"compiled during the walk, not in the warm-up: {new}"


def test_a_failing_warm_up_is_one_warning_and_the_daemon_goes_on(monkeypatch, caplog) -> None:
    from daemon.service import daemon as daemon_module
    from daemon.service.config import DaemonConfig

    def broken(*_args, **_kwargs):
        raise RuntimeError("no device")

    monkeypatch.setattr(daemon_module, "warm_up", broken)
    d = daemon_module.Daemon(DaemonConfig())
    with caplog.at_level(logging.WARNING, logger="guidebelt.daemon"):
        d._warm_up()
    assert [r.getMessage() for r in caplog.records] == ["warm-up failed: RuntimeError: no device"]
