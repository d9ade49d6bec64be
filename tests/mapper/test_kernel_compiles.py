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
