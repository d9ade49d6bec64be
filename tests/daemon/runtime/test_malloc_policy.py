"""``malloc_policy``: with it, memory a step freed serves the next step without the kernel
faulting fresh pages in; without it, glibc gives the heap's top back and the next step pays."""

from __future__ import annotations

import json
import os
import platform
import subprocess
import sys
from pathlib import Path

import pytest

from daemon.runtime import malloc_policy

# Each round holds three 12 MB arrays at once, then frees them: 36 MB free at the heap's top,
# past the trim threshold glibc's default set after the first 16 MB array's free (32 MB).
ROUNDS = """
import json, resource, sys
import numpy as np
from daemon.runtime import malloc_policy
installed = malloc_policy.install() if sys.argv[1] == "policy" else False
faults = lambda: resource.getrusage(resource.RUSAGE_SELF).ru_minflt
a = np.ones(16 << 17)
del a
out = []
for _ in range(4):
    f = faults()
    a = [np.ones(12 << 17) for _ in range(3)]
    del a
    out.append(faults() - f)
print(json.dumps({"installed": installed, "faults": out}))
"""


ROOT = Path(__file__).resolve().parents[3]


def rounds(mode: str) -> dict:
    """A fresh process each: the policy cannot be taken back once installed."""
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    done = subprocess.run([sys.executable, "-c", ROUNDS, mode], capture_output=True, text=True,
                          timeout=60, check=True, env=env)  # fmt: skip
    return json.loads(done.stdout)


glibc_only = pytest.mark.skipif(platform.libc_ver()[0] != "glibc", reason="glibc's mallopt")


@glibc_only
@pytest.mark.timeout(120)
def test_freed_arrays_serve_the_next_round_without_fresh_pages():
    default, policy = rounds("default"), rounds("policy")
    assert policy["installed"]
    # The first round grows the heap either way; after it, only the default faults again,
    # every round (~1 500 faults here: transparent huge pages serve part of the 36 MB).
    assert all(f > 256 for f in default["faults"][1:])
    assert policy["faults"][1:] == [0, 0, 0]


@glibc_only
def test_install_is_idempotent():
    assert malloc_policy.install()
    assert malloc_policy.install()
