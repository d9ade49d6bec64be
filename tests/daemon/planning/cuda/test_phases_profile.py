"""``scripts/profile_cuda_phases.py``'s recording, on a machine without a GPU.

The navigator's ``Route`` steps a ``CudaPlanner`` whose device (the ``cuda`` fixture's
stand-in cupy) serves each call at once: known phase stamps, a path, the done word. The
recording must log every call with the phases the stamps give, and split the step the bench
times (``Route.path_from``) into the call and what the route adds, its own bookkeeping left
out.
"""

from __future__ import annotations

import importlib.util
import sys
import threading
import time
from pathlib import Path

import numpy as np
import pytest

from daemon.planning.cuda import abi

SCRIPT = Path(__file__).parents[4] / "scripts" / "profile_cuda_phases.py"
STAMPS = np.array([1000, 3000, 7000, 8000, 20000, 21000, 22500, 25000, 500], np.uint32)
"""Stamps 0..7 and 8 (the take) in ns: phases take .. walk are 0.5, 2, 4, 1, 12, 1, 1.5, 2.5 µs."""
PHASES_US = [0.5, 2.0, 4.0, 1.0, 12.0, 1.0, 1.5, 2.5]


def instant_planner(cuda, shape: tuple[int, int]):
    """A fast EDS planner whose loop serves each post at once with ``STAMPS`` and a path of
    the start cell and the cell right of it."""
    planner = cuda.planner.CudaPlanner("fast", dss=False)

    class Instant(cuda.resident.ResidentLoop):
        def post(self, slot: int, n_delta: int) -> None:
            super().post(slot, n_delta)
            io, params = planner._io_host.array, planner._stage.array
            io[abi.C_STAMP : abi.C_STAMP + 9] = STAMPS.view(np.int32)
            start = int(params[abi.PARAM_START])
            y, x = divmod(start, shape[1])
            io[abi.IO_PATH], io[abi.IO_PATH + 1] = 2, abi.PATH_DONE
            io[abi.IO_PATH + 2 : abi.IO_PATH + 6] = (y, x, y, x + 1)
            io[abi.IO_REJECT] = 0
            io[abi.IO_DONE] = params[abi.PARAM_SEQ]

    planner._new_loop = lambda: Instant(lambda *a: None).attach((0,) * abi.SLOT_WORDS, ())
    return planner


def load_profile(monkeypatch):
    spec = importlib.util.spec_from_file_location("profile_cuda_phases", SCRIPT)
    assert spec is not None and spec.loader is not None
    profile = importlib.util.module_from_spec(spec)
    monkeypatch.setitem(sys.modules, spec.name, profile)  # its dataclass looks itself up
    spec.loader.exec_module(profile)  # over the stand-in cupy the ``cuda`` fixture installed
    return profile


@pytest.mark.timeout(30)
def test_the_recording_splits_each_step_into_the_call_and_the_route(cuda, monkeypatch):
    profile = load_profile(monkeypatch)
    from daemon.navigation.route import Route

    shape = (40, 60)
    planner = instant_planner(cuda, shape)
    route = Route(lambda backend: planner, "cuda", 10)
    blocked, occupancy = np.zeros(shape, bool), np.zeros(shape, np.int8)
    cells, values = np.array([5, 77], np.int64), np.array([True, False])
    route.path_from(blocked, occupancy, (0, 0), (20, 1))  # the plan: no call to record

    log = profile.CallLog()
    undo = profile.recording(log)
    timed = []
    try:
        for i in range(60):
            route.change(cells, values)
            path, _ = route.path_from(blocked, occupancy, (0, 0), (20, 2 + i % 50))
            assert path.tolist() == [[20, 2 + i % 50], [20, 3 + i % 50]]
            timed.append(route.report.plan_ms)
        route.path_from(blocked, occupancy, (0, 0), (21, 2))  # no change: no update call
    finally:
        undo()
    assert Route.path_from is not None and "profile" not in Route.path_from.__module__

    assert len(log.ms) == 60
    assert np.allclose(log.phases_us(), PHASES_US)
    s = log.summary()
    assert s["all"]["calls"] == 60 and s["all"]["cells"] == 2
    assert s["all"]["walk_us"] == pytest.approx(2.5) and s["all"]["relax_us"] == pytest.approx(12)
    host = np.asarray(log.host_us)
    steps, own = np.asarray(log.step_ms), np.asarray(log.ms)
    # The route's share is the step less the call's wall time (its own time and the
    # combiner's return); the recording's own time is in neither.
    assert (host[:, 4] > 0).all()
    assert (1e3 * steps - host[:, 4] >= 1e3 * own).all()
    assert (steps < np.asarray(timed)).all()
    assert s["step_p99"] >= s["step_median"] > 0
    assert s["all"]["track"] == pytest.approx(np.mean(log.track)) and max(log.track) >= 50
    assert min(log.faults) >= 0 and min(log.preempted) >= 0 and min(log.waited) >= 0
    # The stand-in's steps run on the CPU throughout: off-CPU time is the exception.
    off = np.asarray(log.off_cpu_us)
    assert off.min() >= 0 and np.median(off) < 0.5 * np.median(1e3 * steps)
    calls = log.per_call()
    assert len(calls["step_ms"]) == len(calls["phases_us"]) == len(calls["off_cpu_us"]) == 60
    assert calls["phases_us"][0] == PHASES_US and calls["track"] == log.track
    assert calls["waited"] == log.waited
    # Every step knows the CPU it ran on; a move is counted only where the CPU changed.
    assert min(log.cpu) >= 0 and calls["cpu"] == log.cpu
    assert set(log.moved) <= {0, 1}
    for i in range(1, len(log.cpu)):
        if log.cpu[i] != log.cpu[i - 1]:  # moved during the last step or before this one
            assert log.moved[i - 1] or log.moved[i]


@pytest.mark.timeout(30)
def test_the_host_clocks_name_a_thread_that_ran_beside_the_caller(cuda, monkeypatch) -> None:
    profile = load_profile(monkeypatch)
    stop = threading.Event()

    def spin() -> None:
        while not stop.is_set():
            pass

    before = profile.host_clocks()
    other = threading.Thread(target=spin)
    other.start()
    try:
        time.sleep(0.2)
        after = profile.host_clocks()
    finally:
        stop.set()
        other.join()
    ran = {k: after[k] - before.get(k, 0.0) for k in after if k != "steal"}
    spun = [v for k, v in ran.items() if k.endswith(f":{other.native_id}")]
    assert spun and spun[0] > 0  # 0.2 s of spinning: at least a clock tick of CPU
    assert after["steal"] >= before["steal"] >= 0
