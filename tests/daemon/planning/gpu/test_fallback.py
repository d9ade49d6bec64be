"""A device error mid-session moves the session to the CPU, which replays the failed call.

The first tests run everywhere (CI has no GPU): the wrapped planner is a CPU planner that
raises an injected ``DeviceFault``. The last runs on the GPU machine with a real cupy planner
and a real cupy error type.
"""

from __future__ import annotations

import logging

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from daemon.planning import cuda_available, make_planner
from daemon.planning.dijkstra import dijkstra_field
from daemon.planning.fallback import DeviceFault, FallbackPlanner, device_errors
from daemon.planning.interface import reference_path
from daemon.planning.reference import ReferencePlanner


class FlakyPlanner(ReferencePlanner):
    """A stand-in device planner: raises ``fault`` on the n-th call of ``method``."""

    name = "flaky"

    def __init__(self, method: str, nth: int, fault: BaseException) -> None:
        super().__init__()
        self.method, self.left, self.fault = method, nth, fault

    def _tick(self, method: str) -> None:
        if method == self.method:
            self.left -= 1
            if self.left == 0:
                raise self.fault

    def plan(self, blocked, goal):
        self._tick("plan")
        return super().plan(blocked, goal)

    def update(self, cells, blocked):
        self._tick("update")
        return super().update(cells, blocked)

    def replan(self, cells, blocked):
        self._tick("replan")
        return super().update(cells, blocked)

    def path(self, start):
        self._tick("path")
        return super().path(start)

    def costs(self):
        self._tick("costs")
        return super().costs()


@pytest.fixture(autouse=True)
def _fallback_on(monkeypatch):
    """GPU runs export GUIDEBELT_CUDA_STRICT=1; these tests are about the fallback itself."""
    monkeypatch.delenv("GUIDEBELT_CUDA_STRICT", raising=False)


def scenario(seed: int = 0):
    rng = np.random.default_rng(seed)
    blocked = rng.random((30, 40)) < 0.25
    goal, start = (2, 3), (27, 35)
    blocked[goal] = blocked[start] = False
    deltas = []
    for _ in range(6):
        cells = rng.choice(30 * 40, size=25, replace=False)
        deltas.append((cells, rng.random(25) < 0.5))
    return blocked, goal, start, deltas


@pytest.mark.timeout(60)
@pytest.mark.parametrize("method,nth", [("update", 1), ("update", 4), ("replan", 2), ("plan", 1),
                                        ("path", 3), ("costs", 2)])  # fmt: skip
def test_fault_switches_to_cpu_and_replays_the_call(method, nth, caplog):
    blocked, goal, start, deltas = scenario()
    flaky = FlakyPlanner(method, nth, DeviceFault("injected"))
    planner = FallbackPlanner(flaky, cpu_factory=lambda: make_planner("reference"))
    assert planner.active_backend == "cuda"
    truth = blocked.copy()
    with caplog.at_level(logging.WARNING, logger="daemon.planning.fallback"):
        planner.plan(blocked, goal)
        for i, (cells, values) in enumerate(deltas):
            truth.reshape(-1)[cells] = values
            (planner.replan if i % 3 == 1 else planner.update)(cells, values)
            g = dijkstra_field(truth, goal)
            assert np.array_equal(planner.costs(), g)
            assert np.array_equal(planner.path(start), reference_path(g, truth, start))
    assert planner.active_backend == "cpu"
    assert planner.fell_back and "injected" in planner.fallback_reason
    assert any("continues on the CPU" in r.message for r in caplog.records)
    assert planner.goal == goal and planner.shape == blocked.shape


changes = st.lists(  # deltas of a 10 x 10 map: cells (repeats allowed), one value or one each
    st.lists(st.integers(0, 99), max_size=12).flatmap(
        lambda cells: st.tuples(
            st.just(cells), st.booleans() | st.lists(st.booleans(), min_size=len(cells),
                                                     max_size=len(cells))
        )
    ),
    max_size=3 * FallbackPlanner.FLUSH_AT,
)


@settings(max_examples=40, deadline=None)
@given(changes)
def test_the_mirror_keeps_every_change_in_order(deltas):
    """The host mirror, written in batches, equals the map with each change applied in turn
    (the last value of a cell winning), and a fallback starts the CPU from it."""
    planner = FallbackPlanner(ReferencePlanner(), cpu_factory=lambda: make_planner("reference"))
    truth = np.zeros((10, 10), dtype=bool)
    planner.plan(truth, (0, 0))
    for cells, values in deltas:
        planner.update(np.array(cells, dtype=np.int64), np.array(values, dtype=bool))
        each = values if isinstance(values, list) else [values] * len(cells)
        for cell, value in zip(cells, each, strict=True):
            truth.reshape(-1)[cell] = value
    assert np.array_equal(planner.mirrored_blocked(), truth)
    planner._switch(DeviceFault("injected"))
    assert np.array_equal(planner.blocked(), truth)


class HookedPlanner(ReferencePlanner):
    """A stand-in for CudaPlanner's update_and_path: runs the ``while_waiting`` hook (where the
    fallback makes its mirror copies), then fails with ``fault`` on the n-th call."""

    name = "hooked"

    def __init__(self, nth: int, fault: BaseException) -> None:
        super().__init__()
        self.while_waiting = None
        self.left, self.fault = nth, fault

    def update_and_path(self, cells, blocked, start, *, full=False):
        if self.while_waiting is not None:
            self.while_waiting()
        self.left -= 1
        if self.left == 0:
            raise self.fault
        return super().update_and_path(cells, blocked, start, full=full)


@pytest.mark.parametrize(
    "nth,bad_at", [(1, 0), (3, 4), (99, 2)], ids=["fault-on-bad", "fault-then-bad", "bad-no-fault"]
)
def test_a_step_that_fails_after_its_copies_leaves_the_mirror_exact(nth, bad_at):
    """update_and_path fails on the device (its nth call) after the hook copied its change:
    the CPU replays the step from the mirror. A delta with a cell outside the map (before step
    ``bad_at``) raises and is recorded nowhere, whether the device fault came with it, before
    it or not at all (the device planner refuses it after the hook copied it): the mirror, the
    field and the path stay those of the good steps only."""
    blocked, goal, start, deltas = scenario(1)
    hooked = HookedPlanner(nth, DeviceFault("injected"))
    planner = FallbackPlanner(hooked, cpu_factory=lambda: make_planner("reference"))
    planner.plan(blocked, goal)
    truth = blocked.copy()
    for i, (cells, values) in enumerate(deltas):
        if i == bad_at:  # out of the map: rejected whole, on whichever backend is active
            with pytest.raises(IndexError):
                planner.update_and_path(np.array([cells[0], 30 * 40]), [True, True], start)
        truth.reshape(-1)[cells] = values
        _, path = planner.update_and_path(cells, values, start, full=i % 2 == 1)
        g = dijkstra_field(truth, goal)
        assert np.array_equal(path, reference_path(g, truth, start)), f"step {i}"
        assert np.array_equal(planner.mirrored_blocked(), truth), f"step {i}"
        assert hooked.while_waiting is None
    assert planner.active_backend == ("cpu" if nth < len(deltas) else "cuda")


def test_other_errors_are_not_swallowed():
    planner = FallbackPlanner(ReferencePlanner(), cpu_factory=lambda: make_planner("reference"))
    planner.plan(np.zeros((4, 4), bool), (0, 0))
    with pytest.raises(IndexError):
        planner.update(np.array([99]), np.array([True]))
    assert planner.active_backend == "cuda"


def test_strict_mode_lets_device_errors_through(monkeypatch):
    monkeypatch.setenv("GUIDEBELT_CUDA_STRICT", "1")
    planner = FallbackPlanner(FlakyPlanner("plan", 1, DeviceFault("boom")))
    with pytest.raises(DeviceFault):
        planner.plan(np.zeros((4, 4), bool), (0, 0))


def test_device_errors_always_include_the_injected_fault():
    assert DeviceFault in device_errors()


@pytest.mark.gpu
@pytest.mark.timeout(120)
@pytest.mark.skipif(not cuda_available(), reason="no usable CUDA device")
@pytest.mark.parametrize("variant", ["fast", "paper"])
def test_real_cuda_planner_falls_back_on_a_cupy_error(variant):
    import cupy

    from daemon.planning.cuda_planner import CudaPlanner

    blocked, goal, start, deltas = scenario(1)
    cuda = CudaPlanner(variant)
    planner = FallbackPlanner(cuda, errors=device_errors())
    wrapped = make_planner("cuda", variant)
    assert isinstance(wrapped, FallbackPlanner) and wrapped.active_backend == "cuda"
    truth = blocked.copy()
    planner.plan(blocked, goal)
    for i, (cells, values) in enumerate(deltas):
        if i == 2:  # an illegal address, as a faulting kernel would report it
            cuda.inject_fault(cupy.cuda.runtime.CUDARuntimeError(700))
        truth.reshape(-1)[cells] = values
        planner.update(cells, values)
        assert planner.active_backend == ("cuda" if i < 2 else "cpu")
        g = dijkstra_field(truth, goal)
        assert np.array_equal(planner.costs(), g)
        assert np.array_equal(planner.path(start), reference_path(g, truth, start))
