"""The C heap kept resident, so a large step does not pay the kernel for fresh pages.

numpy's arrays come from glibc's ``malloc``. By default glibc serves a request above a
threshold (128 KiB, raised as the program frees larger ones) with a fresh ``mmap``, and gives
the top of its heap back to the kernel once more than twice that threshold lies free there. A
step that builds ~1 MB temporaries (a 2000² map's 119 k- and 137 k-cell deltas: padded cell
indices, the cells lost, the device search's answer) then gets pages the kernel must fault in
and zero, one 4 KiB page at a time, and whether it does depends on what the process freed
before. Replaying the 2000² bench walk's recorded deltas through ``Reach`` (dev VM, CPU time):
~230–440 minor faults and +1.2 to +6 ms on the two largest deltas in every other replay, none
with this policy; at 400² the whole-map search's step, 202 faults and +0.4 ms. On the H100
host the same two steps took 1.7 and 2.2 ms longer in the bench's process than in the
profiler's, every other step within 0.2 ms (it sets the 2000² p99).

The usual policy of real-time programs on glibc (its manual's "Malloc Tunable Parameters"):
``M_MMAP_MAX`` 0, no request served by ``mmap``, and ``M_TRIM_THRESHOLD`` -1, the heap's top
never given back. Memory a step frees stays resident and serves the next step. The price: the
process holds its largest heap since start (the users it served at their peak) until it
exits; a departed user's arrays serve the next user's. Where a request cannot grow the main
heap glibc still falls back to ``mmap`` (a worker thread's arena does too), so no request
fails for the policy.

``install()`` at process start, before the warm-up: the daemon, and the benchmarks that
measure it. Other C libraries (musl, macOS) keep their own behaviour: ``install`` says False.
"""

from __future__ import annotations

import ctypes
import platform

M_TRIM_THRESHOLD = -1
M_MMAP_MAX = -4
"""``mallopt``'s parameters, as glibc's ``malloc.h`` numbers them."""

_installed = False


def install() -> bool:
    """Apply the policy to this process (idempotent); False where the C library is not glibc
    or refused a setting."""
    global _installed
    if _installed:
        return True
    if platform.libc_ver()[0] != "glibc":
        return False
    libc = ctypes.CDLL(None)
    mallopt = libc.mallopt
    mallopt.argtypes = [ctypes.c_int, ctypes.c_int]
    mallopt.restype = ctypes.c_int
    # -1 as the trim threshold: glibc's "disables trimming completely".
    _installed = bool(mallopt(M_MMAP_MAX, 0)) and bool(mallopt(M_TRIM_THRESHOLD, -1))
    return _installed
