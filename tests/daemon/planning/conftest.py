"""The planners under test: every backend and variant runs the same tests.

``cpu-fast-repair`` is the fast CPU planner that never cuts over to a full plan, so the
repair itself meets every property test. ``cuda-*`` cases are marked ``gpu`` and skipped
where no CUDA device answers, so the GPU machine runs exactly these tests with
``pytest -m gpu``.
"""

from __future__ import annotations

import ctypes
from collections.abc import Callable
from pathlib import Path

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
