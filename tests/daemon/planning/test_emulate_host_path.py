"""scripts/emulate_host_path.py, the cuda backend's host path without a GPU, keeps running.

It builds a CudaPlanner around mocked cupy and stand-in buffers; this test catches the day
the planner's state or the resident loop's host side changes under it. The script checks
itself that the emulated step returns the CPU planner's path at every step of the walk.
"""

from __future__ import annotations

import re
import subprocess
import sys
from pathlib import Path

import pytest

SCRIPT = Path(__file__).resolve().parents[3] / "scripts" / "emulate_host_path.py"


@pytest.mark.timeout(120)
def test_the_emulated_host_path_walks_and_reports_its_time():
    out = subprocess.run(
        [sys.executable, str(SCRIPT), "--grid", "100", "--walks", "1", "--mode", "eds"],
        capture_output=True, text=True, timeout=110, check=True,
    ).stdout  # fmt: skip
    steps = re.search(r"walk 1: (\d+) steps", out)
    total = re.search(r"median over walks: ([\d.]+) µs", out)
    assert steps and int(steps.group(1)) > 50, out
    assert total and 0 < float(total.group(1)) < 10_000, out
