"""A cached jitted function is compiled again when a jitted function it calls changes file."""

from __future__ import annotations

import os
import subprocess
import sys
import textwrap
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]

CALLER = """
from numba import njit
from callee import step

@njit(cache=True)
def walk(x):
    return step(x) * 10
"""
CALLEE = """
from numba import njit

@njit(cache=True)
def step(x):
    return x + {k}
"""


def _run(folder: Path) -> int:
    """A fresh process (so the compiled code comes from the disk cache when it is there)."""
    code = "import daemon, caller; print(caller.walk(1))"
    env = dict(os.environ, PYTHONPATH=f"{folder}{os.pathsep}{ROOT}")
    env.pop("NUMBA_CACHE_DIR", None)
    env.pop("NUMBA_CACHE_LOCATOR_CLASSES", None)
    out = subprocess.run(
        [sys.executable, "-c", code], env=env, capture_output=True, text=True, timeout=120
    )
    assert out.returncode == 0, out.stderr
    return int(out.stdout.strip())


@pytest.mark.timeout(240)
def test_editing_only_the_callee_recompiles_the_cached_caller(tmp_path: Path) -> None:
    (tmp_path / "caller.py").write_text(textwrap.dedent(CALLER))
    callee = tmp_path / "callee.py"
    callee.write_text(textwrap.dedent(CALLEE.format(k=1)))
    assert _run(tmp_path) == 20
    assert list((tmp_path / "__pycache__").glob("caller.walk-*.nbi")), "the caller was cached"
    callee.write_text(textwrap.dedent(CALLEE.format(k=2)))
    # numba alone stamps caller.walk with caller.py only and would answer 20 from its cache
    assert _run(tmp_path) == 30


def test_the_stamp_names_the_files_a_compiled_step_is_built_from() -> None:
    from daemon.numba_cache import source_files
    from daemon.planning.cpu import repair

    names = {Path(f).name for f in source_files(repair.step.py_func)}
    assert {"repair.py", "repair_queue.py"} <= names
