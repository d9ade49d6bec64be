"""``kernels/harmonic.cu`` and ``harmonic_reach.cu``, joined as cuda.py joins them, compile
with NVRTC (what CuPy uses) for the H100's sm_90, in both float types, on a machine without a
GPU — as ``test_kernels_compile.py`` does for the cuda planner's kernels. (A name NVRTC lacks,
``INFINITY``, once reached the device.)"""

from __future__ import annotations

import ctypes
from pathlib import Path

import pytest

KERNELS = Path(__file__).resolve().parents[4] / "daemon" / "planning" / "harmonic" / "kernels"
SOURCES = (KERNELS / "harmonic.cu", KERNELS / "harmonic_reach.cu")  # joined as cuda.py does


def cuda_include(lib: ctypes.CDLL) -> Path:
    """The CUDA headers (cooperative_groups.h): cupy passes its toolkit's; here the system's
    toolkit or the nvidia-cuda-runtime wheel's."""
    import glob
    import sys

    found = [Path("/usr/local/cuda/include")] + [
        Path(p) for p in glob.glob(f"{sys.prefix}/lib/python3*/site-packages/nvidia/*/include")
    ]
    major, minor = ctypes.c_int(), ctypes.c_int()
    lib.nvrtcVersion(ctypes.byref(major), ctypes.byref(minor))
    for folder in found:
        header = folder / "cuda.h"
        if (folder / "cooperative_groups.h").exists() and header.exists():
            # Headers of another major version than NVRTC's do not parse (CUDA 13's with
            # NVRTC 12): only a matching pair says anything about the kernel.
            text = header.read_text(errors="replace")
            at = text.find("#define CUDA_VERSION")
            if at >= 0 and int(text[at:].split()[2]) // 1000 == major.value:
                return folder
    pytest.skip(f"no CUDA {major.value}.x headers with cooperative_groups.h on this machine")


@pytest.mark.parametrize("real,eps", [("float", "1.1920929e-7f"), ("double", "2.2e-16")])
def test_the_harmonic_kernel_compiles_for_sm90(nvrtc, real, eps):
    include = cuda_include(nvrtc.lib)
    # -rdc: grid-wide sync (cooperative groups) needs relocatable device code, as cupy's
    # enable_cooperative_groups compiles it.
    opts = [b"--std=c++17", b"--gpu-architecture=sm_90", b"-rdc=true", f"-I{include}".encode(),
            f"-I{include / 'cccl'}".encode(),
            f"-DREAL={real}".encode(), f"-DREAL_EPS={eps}".encode()]  # fmt: skip
    rc, log = nvrtc.compile(b"".join(p.read_bytes() for p in SOURCES), "harmonic.cu", opts)
    assert rc == 0, log
