"""What the host's clocks say about the threads of this process, for a profile that must
tell a step that ran slowly from one that did not run (``scripts/profile_cuda_phases.py``):
the CPU a thread is on, each thread's CPU time, and the time the hypervisor stole."""

from __future__ import annotations

import ctypes
import os


def getcpu() -> int:
    """The CPU the calling thread runs on (glibc's ``sched_getcpu``, ~0.1 µs); -1 without."""
    return _GETCPU() if _GETCPU is not None else -1


try:
    _GETCPU = ctypes.CDLL(None).sched_getcpu
except (OSError, AttributeError):
    _GETCPU = None


def host_clocks() -> dict[str, float]:
    """CPU ms of each of the process's threads (``comm:tid``) and the machine's stolen ms
    (``/proc/stat``'s steal): read around a walk, they name the threads that ran beside the
    stepping one and whether the hypervisor took the vCPUs, what a step's ``off_cpu`` alone
    cannot say. Empty where ``/proc`` is missing."""
    tick = 1e3 / os.sysconf("SC_CLK_TCK")
    out: dict[str, float] = {}
    try:
        tids = os.listdir("/proc/self/task")
    except OSError:
        return out
    for tid in tids:
        try:
            with open(f"/proc/self/task/{tid}/stat") as f:
                stat = f.read()
        except OSError:  # the thread ended since the listing: the others still count
            continue
        comm = stat[stat.index("(") + 1 : stat.rindex(")")]
        fields = stat[stat.rindex(")") + 2 :].split()
        out[f"{comm}:{tid}"] = tick * (int(fields[11]) + int(fields[12]))  # utime, stime
    try:
        with open("/proc/stat") as f:
            cpu = f.readline().split()
        out["steal"] = tick * int(cpu[8])
    except (OSError, ValueError, IndexError):
        pass
    return out
