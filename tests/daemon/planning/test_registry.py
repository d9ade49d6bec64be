"""Planners by name, the interface's default step, and the device errors a caller catches."""

from __future__ import annotations

import subprocess
import sys

import numpy as np
import pytest

from daemon.planning import (
    PLANNERS,
    DeviceFault,
    GlobalPlanner,
    UpdateStats,
    device_errors,
    make_planner,
    register,
    resolve_backend,
)
from daemon.planning.dijkstra import dijkstra_field, reference_path
from daemon.planning.reference import ReferencePlanner


def test_eds_and_dss_are_registered_on_every_backend_and_variant():
    assert {"eds", "dss"} <= set(PLANNERS)
    for name in ("eds", "dss"):
        for backend, variant in (("cpu", "fast"), ("cpu", "paper"), ("reference", "fast")):
            planner = make_planner(name, backend, variant)
            assert isinstance(planner, GlobalPlanner)
            assert planner.name.startswith(name) and planner.dss == (name == "dss")


def test_unknown_names_are_clear_errors():
    for kwargs in ({"name": "nope"}, {"backend": "tpu"}, {"variant": "slow"}):
        with pytest.raises(ValueError):
            make_planner(**kwargs)


def test_auto_resolves_to_a_real_backend():
    assert resolve_backend("auto") in ("cpu", "cuda")
    assert resolve_backend("cpu") == "cpu"


def test_a_new_planner_registers_by_name():
    seen = []

    def factory(backend: str, variant: str) -> GlobalPlanner:
        seen.append((backend, variant))
        return ReferencePlanner()

    register("test-only", factory)
    try:
        assert "test-only" in PLANNERS
        assert isinstance(make_planner("test-only", "cpu"), ReferencePlanner)
        assert seen == [("cpu", "fast")]
        with pytest.raises(ValueError):
            register("test-only", factory)
    finally:
        del PLANNERS["test-only"]


@pytest.mark.parametrize("name", ["eds", "dss"])
@pytest.mark.parametrize(
    "backend,variant", [("cpu", "fast"), ("cpu", "paper"), ("reference", "fast")]
)
def test_the_default_step_equals_update_then_path(name, backend, variant):
    rng = np.random.default_rng(0)
    blocked = rng.random((30, 40)) < 0.25
    goal = (1, 2)
    blocked[goal] = False
    fused, split = make_planner(name, backend, variant), make_planner(name, backend, variant)
    fused.plan(blocked, goal)
    split.plan(blocked, goal)
    truth = blocked.copy()
    for _ in range(8):
        cells = rng.choice(30 * 40, size=25, replace=False)
        values = rng.random(25) < 0.5
        start = (int(rng.integers(30)), int(rng.integers(40)))
        truth.reshape(-1)[cells] = values
        stats, path = fused.update_and_path(cells, values, start)
        want = split.update(cells, values)
        assert isinstance(stats, UpdateStats) and stats.ms >= 0
        assert isinstance(want, UpdateStats)  # (their counts differ: a query repairs lazily)
        g = dijkstra_field(truth, goal)
        assert np.array_equal(fused.costs(), g)
        assert np.array_equal(path, split.path(start))
        assert np.array_equal(path, reference_path(g, truth, start))


def test_device_errors_include_the_injected_fault():
    assert DeviceFault in device_errors()
    assert all(issubclass(e, BaseException) for e in device_errors())


def test_the_package_and_its_device_errors_import_without_cupy():
    """The navigator asks for ``device_errors`` on every machine: it must not need cupy."""
    code = (
        "import sys; sys.modules['cupy'] = None\n"
        "import daemon.planning as p\n"
        "assert p.device_errors() == (p.DeviceFault,)\n"
        "assert sys.modules['cupy'] is None\n"
    )
    subprocess.run([sys.executable, "-c", code], check=True)
