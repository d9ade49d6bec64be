"""The mapper's CUDA kernel compiles for the H100 (sm_90) without warnings, on a machine
without a GPU: NVRTC from the ``nvidia-cuda-nvrtc-cu12`` wheel, as the planner's kernels."""

from __future__ import annotations

from pathlib import Path

import pytest

KERNEL = Path(__file__).resolve().parents[2] / "mapper" / "kernels" / "bin_pixels.cu"


@pytest.mark.parametrize("defines", [(), ("DEPTH_FLOAT",)], ids=["uint16", "float"])
def test_bin_pixels_compiles_for_sm90(nvrtc, defines):
    rc, log = nvrtc.compile_file(KERNEL, defines)
    assert rc == 0, log
    assert "warning" not in log.lower(), log


def test_merge_cells_compiles_for_sm90_without_fused_multiply_adds(nvrtc):
    """The device's merge, built as ``cuda_merge.merge_kernel`` builds it (no fused
    multiply-adds: the CPU's rounding), compiles clean."""
    path = KERNEL.with_name("merge_cells.cu")
    opts = [b"--std=c++17", b"--gpu-architecture=sm_90", b"--fmad=false"]
    rc, log = nvrtc.compile(path.read_bytes(), path.name, opts)
    assert rc == 0, log
    assert "warning" not in log.lower(), log
