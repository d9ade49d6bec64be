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


@pytest.mark.parametrize("planner", list(PLANNERS))
def test_after_the_warm_up_a_walk_compiles_nothing(planner: str) -> None:
    # A world walked first, untimed: the simulator's own compiled code is not the product's.
    scenario = make_scenario("courtyard", 50, 0.4, 0)
    assert warm_up(planner, "cpu") > 0
    before = numba_signatures()
    walk(scenario, mode=planner, max_steps=60)
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
