"""The mapper's CUDA kernel compiles for the H100 (sm_90) without warnings, on a machine
without a GPU: NVRTC from the ``nvidia-cuda-nvrtc-cu12`` wheel, as the planner's kernels."""

from __future__ import annotations

import importlib.util
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]


def _planner_check():
    spec = importlib.util.spec_from_file_location(
        "kernels_compile", ROOT / "tests/daemon/planning/test_kernels_compile.py"
    )
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


@pytest.mark.parametrize("defines", [(), ("DEPTH_FLOAT",)], ids=["uint16", "float"])
def test_bin_pixels_compiles_for_sm90(defines):
    check = _planner_check()
    rc, log = check.compile_kernel(check.nvrtc(), "bin_pixels", defines, ROOT / "mapper/kernels")
    assert rc == 0, log
    assert "warning" not in log.lower(), log
