"""A real daemon on a thread, on a free 127.0.0.1 port, multicast scouting off.

Shared by the service, CLI and simulator tests. The daemon's modules (pydantic, zenoh) are
imported inside the fixtures: the GPU machine, which has neither, collects these tests too.
"""

from __future__ import annotations

import ctypes
import gc
import threading
import time
from pathlib import Path

import numpy as np
import pytest


def warm_up() -> None:
    """Compile (or load from numba's cache) the planner and guidance once, before any
    test's own time limits run: a cold compile takes 10-20 s on a loaded machine. The
    first test of each module carries this in its (generous) timeout."""
    from daemon.navigation import Inbox, Navigator
    from daemon.service.config import DaemonConfig
    from protocol.messages import Goal, GoalCell, MapDelta, Pose

    s = Navigator("warm", DaemonConfig(backend="cpu").navigator_settings())
    now = time.time()
    inbox = Inbox(
        deltas=[MapDelta.from_arrays(0, (20, 20), np.array([0]), np.array([1]), now)],
        goal=Goal(target=GoalCell(row=5, col=10), stamp=now),
        pose=Pose(x=1.0, y=0.5, heading=1.5, stamp=now),
    )
    s.step(inbox, now)
    from daemon.navigation.warm import warm_up as warm_daemon

    warm_daemon("eds", "cpu")  # what the daemon compiles before READY, compiled here first


def daemon_threads() -> list[threading.Thread]:
    return [t for t in threading.enumerate() if t.name.startswith(("guidebelt-daemon", "plan-"))]


@pytest.fixture(scope="module")
def daemon():
    from daemon.service.embedded import DaemonThread

    warm_up()
    # Tests of behaviour, not of load: a slow CI machine must not make this daemon shed
    # users (admission control has tests of its own, tests/daemon/service/test_admission.py).
    # A pose alone re-guides at 100 Hz, not 10: a lock-step walk is not paced by the limit
    # (its own tests: tests/daemon/service/test_runner_and_config.py).
    with DaemonThread(
        backend="cpu", lag_budget_ms=10_000, step_cpu_budget_ms=1_000_000, guide_hz=100
    ) as d:
        yield d
    # No leaks: the loop thread and every user's worker are gone once the daemon stops.
    deadline = time.monotonic() + 3.0
    while daemon_threads() and time.monotonic() < deadline:
        time.sleep(0.05)
    assert not daemon_threads(), daemon_threads()


@pytest.fixture
def peer(daemon):
    session = daemon.peer()
    yield session
    session.close()


class Nvrtc:
    """NVRTC, the runtime compiler CuPy itself uses, from the ``nvidia-cuda-nvrtc-cu12`` wheel
    of the ``test`` extra: the kernels compile for the H100's sm_90 on a machine without a GPU."""

    def __init__(self, lib: ctypes.CDLL) -> None:
        self.lib = lib

    def compile(self, source: bytes, name: str, opts: list[bytes]) -> tuple[int, str]:
        """(NVRTC's result code, its log) for ``source`` compiled with ``opts``."""
        lib, prog = self.lib, ctypes.c_void_p()
        rc = lib.nvrtcCreateProgram(ctypes.byref(prog), source, name.encode(), 0, None, None)
        assert rc == 0, f"nvrtcCreateProgram: {rc}"
        try:
            rc = lib.nvrtcCompileProgram(prog, len(opts), (ctypes.c_char_p * len(opts))(*opts))
            size = ctypes.c_size_t()
            lib.nvrtcGetProgramLogSize(prog, ctypes.byref(size))
            log = ctypes.create_string_buffer(size.value)
            lib.nvrtcGetProgramLog(prog, log)
            return rc, log.value.decode(errors="replace")
        finally:
            lib.nvrtcDestroyProgram(ctypes.byref(prog))

    def compile_file(self, path: Path, defines: tuple[str, ...] = ()) -> tuple[int, str]:
        """``path`` (a ``.cu`` file) for sm_90, its folder on the include path, with ``defines``."""
        opts = [b"--std=c++17", f"-I{path.parent}".encode(), b"--gpu-architecture=sm_90"]
        opts += [f"-D{d}".encode() for d in defines]
        return self.compile(path.read_bytes(), path.name, opts)


@pytest.fixture
def nvrtc() -> Nvrtc:
    try:
        import nvidia.cuda_nvrtc as pkg
    except ImportError:
        pytest.skip("nvidia-cuda-nvrtc-cu12 is not installed (pip install -e '.[test]')")
    libs = sorted(Path(next(iter(pkg.__path__))).glob("lib/libnvrtc.so*"))
    if not libs:
        pytest.skip("the nvrtc wheel holds no libnvrtc.so for this platform")
    return Nvrtc(ctypes.CDLL(str(libs[0])))


@pytest.fixture
def collector_restored():
    """The interpreter's collector thresholds and frozen set as they were before the test."""
    threshold = gc.get_threshold()
    yield
    gc.set_threshold(*threshold)
    gc.unfreeze()
