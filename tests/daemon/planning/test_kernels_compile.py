"""Every CUDA kernel compiles, in every variant the planner builds, on a machine without a GPU.

CI has no GPU, so the GPU tests skip there; this test still compiles ``kernels/*.cu`` with
NVRTC (the runtime compiler CuPy itself uses, from the ``nvidia-cuda-nvrtc-cu12`` wheel of the
``test`` extra) for the H100's sm_90, through ptxas, and fails on any error or warning. It
skips only where that wheel is not installed.
"""

from __future__ import annotations

import ctypes
from pathlib import Path

import pytest

KERNELS = Path(__file__).resolve().parents[3] / "daemon" / "planning" / "kernels"

# (file, defines): what CudaPlanner compiles (cuda_planner.py: SCANS, SCHED, MIN_BLOCKS and
# PROFILE for fast.cu; path_tiles.cu and path.cu for the path; paper.cu for the paper's form).
VARIANTS = [
    ("fast", ("SCANS=2", "SCHED=1", "MIN_BLOCKS=1")),
    ("fast", ("SCANS=2", "SCHED=0", "MIN_BLOCKS=1")),
    ("fast", ("SCANS=0", "SCHED=1", "MIN_BLOCKS=2")),
    ("fast", ("SCANS=1", "SCHED=1", "MIN_BLOCKS=1")),
    ("fast", ("SCANS=2", "SCHED=1", "MIN_BLOCKS=1", "PROFILE=1")),
    ("path_tiles", ()),
    ("path", ()),
    ("paper", ()),
]


def nvrtc() -> ctypes.CDLL:
    try:
        import nvidia.cuda_nvrtc as pkg
    except ImportError:
        pytest.skip("nvidia-cuda-nvrtc-cu12 is not installed (pip install -e '.[test]')")
    libs = sorted(Path(next(iter(pkg.__path__))).glob("lib/libnvrtc.so*"))
    if not libs:
        pytest.skip("the nvrtc wheel holds no libnvrtc.so for this platform")
    return ctypes.CDLL(str(libs[0]))


def compile_kernel(
    lib: ctypes.CDLL, name: str, defines: tuple[str, ...], folder: Path = KERNELS
) -> tuple[int, str]:
    """(NVRTC's result code, its log) for <folder>/<name>.cu compiled for sm_90."""
    prog = ctypes.c_void_p()
    src = (folder / f"{name}.cu").read_bytes()
    rc = lib.nvrtcCreateProgram(ctypes.byref(prog), src, f"{name}.cu".encode(), 0, None, None)
    assert rc == 0, f"nvrtcCreateProgram: {rc}"
    try:
        opts = [b"--std=c++17", f"-I{folder}".encode(), b"--gpu-architecture=sm_90"]
        opts += [f"-D{d}".encode() for d in defines]
        rc = lib.nvrtcCompileProgram(prog, len(opts), (ctypes.c_char_p * len(opts))(*opts))
        size = ctypes.c_size_t()
        lib.nvrtcGetProgramLogSize(prog, ctypes.byref(size))
        log = ctypes.create_string_buffer(size.value)
        lib.nvrtcGetProgramLog(prog, log)
        return rc, log.value.decode(errors="replace")
    finally:
        lib.nvrtcDestroyProgram(ctypes.byref(prog))


@pytest.mark.parametrize(
    "name,defines", VARIANTS, ids=lambda v: v if isinstance(v, str) else ",".join(v) or "-"
)
def test_kernel_compiles_for_sm90_without_warnings(name, defines):
    rc, log = compile_kernel(nvrtc(), name, defines)
    assert rc == 0, f"{name}.cu {defines} does not compile:\n{log}"
    assert "warning" not in log.lower(), f"{name}.cu {defines}:\n{log}"


def test_a_broken_kernel_is_reported(tmp_path):
    """The check itself: a kernel with an error fails with NVRTC's message."""
    lib = nvrtc()
    (tmp_path / "broken.cu").write_text('extern "C" __global__ void k(int* a) { a[0] = b; }\n')
    rc, log = compile_kernel(lib, "broken", (), folder=tmp_path)
    assert rc != 0 and 'identifier "b" is undefined' in log
