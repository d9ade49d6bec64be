"""Every CUDA kernel the planner builds compiles on a machine without a GPU.

CI has no GPU, so the GPU tests skip there; this test still compiles ``kernels/*.cu`` with
NVRTC (the runtime compiler CuPy itself uses, from the ``nvidia-cuda-nvrtc-cu12`` wheel of the
``test`` extra) for the H100's sm_90, through ptxas, and fails on any error or warning. It
skips only where that wheel is not installed.
"""

from __future__ import annotations

from pathlib import Path

import pytest

KERNELS = Path(__file__).resolve().parents[3] / "daemon" / "planning" / "cuda" / "kernels"

# What CudaPlanner compiles: fast.cu (the resident loop), path_tiles.cu (a path outside a fast
# call), paper.cu (the paper's Figure 4 form); and fast.cu as scripts/profile_cuda_links.py
# builds it (kernels/profile.cuh).
VARIANTS = [("fast", ()), ("path_tiles", ()), ("paper", ()), ("fast", ("GB_PROFILE",))]


def compile_kernel(
    nvrtc, name: str, defines: tuple[str, ...], folder: Path = KERNELS
) -> tuple[int, str]:
    """(NVRTC's result code, its log) for <folder>/<name>.cu compiled for sm_90."""
    return nvrtc.compile_file(folder / f"{name}.cu", defines)


@pytest.mark.parametrize(
    "name,defines", VARIANTS, ids=lambda v: v if isinstance(v, str) else ",".join(v) or "-"
)
def test_kernel_compiles_for_sm90_without_warnings(nvrtc, name, defines):
    rc, log = compile_kernel(nvrtc, name, defines)
    assert rc == 0, f"{name}.cu {defines} does not compile:\n{log}"
    assert "warning" not in log.lower(), f"{name}.cu {defines}:\n{log}"


def test_a_broken_kernel_is_reported(nvrtc, tmp_path):
    """The check itself: a kernel with an error fails with NVRTC's message."""
    (tmp_path / "broken.cu").write_text('extern "C" __global__ void k(int* a) { a[0] = b; }\n')
    rc, log = compile_kernel(nvrtc, "broken", (), folder=tmp_path)
    assert rc != 0 and 'identifier "b" is undefined' in log


def test_the_checked_in_abi_header_is_generated_from_abi_py():
    """``kernels/abi.cuh`` is what ``python -m daemon.planning.cuda.abi`` writes: the numbers host
    and device exchange cannot drift apart (regenerate it after changing ``abi.py``)."""
    from daemon.planning.cuda import abi

    regenerate = "stale: run python -m daemon.planning.cuda.abi"
    assert (KERNELS / "abi.cuh").read_text() == abi.header(), regenerate


def test_no_kernel_types_a_number_the_abi_owns():
    """The shared words and the neighbour table are defined only in the generated header."""
    from daemon.planning.cuda import abi

    owned = ("INF", "STRAIGHT", "DIAGONAL", *abi._WORDS)
    for src in KERNELS.glob("*.cu*"):
        if src.name == "abi.cuh":
            continue
        text = src.read_text()
        for name in owned:
            assert f"#define {name} " not in text, f"{src.name} defines {name}"
        assert "{-1, -1, -1, 0, 0, 1, 1, 1}" not in text, f"{src.name} types the neighbour table"
