"""Many users' walking steps as one batch on the device (issue 28).

The steps that fall due together (every user's ``update_and_path``: the delta, the repair,
the path) go to the device's resident loop as one post (``ResidentLoop.post_batch``): the
loop serves them side by side, each on a group of its blocks (``kernels/resident.cuh``), and
each planner's results come back into its own mapped buffer, read as after a call of its own.
Served one at a time, every step held all the SMs while its few tiles' work left most of them
waiting at its barriers: one host thread topped out at ~9,200 steps/s at 400² (H200), short
of 1,000 users at 10 Hz.

A batch holds each planner once (a planner has one call in flight); a step that fails (a
delta outside the map, a device fault) is returned as its exception, in its place, and the
others are still served. The cuda backend's EDS (``SmallGridsOnCpu``) is batched when its map
is served by the device; other planners step one after another, as their own
``update_and_path`` does.
"""

from __future__ import annotations

import time
from collections.abc import Sequence
from typing import Any

import numpy as np

from . import abi, device, resident
from .planner import CudaPlanner
from .small_grids import SmallGridsOnCpu

Step = tuple[Any, np.ndarray, np.ndarray, tuple[int, int]]
"""(planner, cells, blocked, start): one user's ``update_and_path``."""


GROUP_MIN = 8
"""Blocks a batched call gets at least: a post holds at most the loop's blocks / GROUP_MIN
calls. A post ends when its slowest call does, and a call that recomputes its field (the
cut-over) or all its exits on one block takes milliseconds."""


def batch_size() -> int:
    """Calls a post holds: the device's resident loop blocks / ``GROUP_MIN``."""
    blocks = device.resident_blocks(device.kernel("fast", "plan_users"))
    return max(1, min(abi.BATCH_MAX, blocks // GROUP_MIN))


def step_many(steps: Sequence[Step], max_batch: int | None = None) -> list[Any]:
    """Every step's ``(UpdateStats, path)``, or the exception it raised, in order. The fast
    cuda planners' steps go to the device in posts of up to ``max_batch`` calls (default
    ``batch_size()``), one after another."""
    if len({id(step[0]) for step in steps}) != len(steps):
        raise ValueError("a batch holds each planner once")
    out: list[Any] = [None] * len(steps)
    planners: dict[int, CudaPlanner] = {}
    for i, (p, cells, blocked, start) in enumerate(steps):
        if isinstance(p, SmallGridsOnCpu):  # the cuda backend's EDS: which one serves the map
            p = p._serving
        if isinstance(p, CudaPlanner) and p.variant == "fast":
            planners[i] = p
            continue
        try:
            out[i] = steps[i][0].update_and_path(cells, blocked, start)
        except Exception as exc:  # one user's failure is that user's result
            out[i] = exc
    fast = list(planners)
    size = min(max_batch or batch_size(), abi.BATCH_MAX)
    for at in range(0, len(fast), size):
        _batch(steps, planners, fast[at : at + size], out)
    return out


def _batch(
    steps: Sequence[Step], planners: dict[int, CudaPlanner], which: list[int], out: list[Any]
) -> None:
    with device.DEVICE_LOCK:
        t0 = time.perf_counter()
        staged: list[tuple[int, CudaPlanner, tuple]] = []
        for i in which:
            p, (_, cells, blocked, start) = planners[i], steps[i]
            try:
                staged.append((i, p, p._stage_step(cells, blocked, start)))
            except Exception as exc:
                out[i] = exc
        if not staged:
            return
        # Staging may stop the loop (a buffer that grows, a table that grows) or attach a
        # planner: only once every step is staged are the slots final.
        loop = resident.shared()
        calls = np.empty((len(staged), 2), dtype=np.int32)
        for row, (_, p, step) in enumerate(staged):
            slot = p._loop
            assert slot is not None and slot.loop is loop, "one loop per process"
            calls[row] = slot.index, step[2]
        loop.post_batch(calls)
        for i, p, step in staged:
            try:
                loop.wait(p._io_host.view, step[1])
            except Exception as exc:  # a CUDA fault: every step has it
                out[i] = exc
        for i, p, step in staged:
            if out[i] is not None:
                continue
            try:
                out[i] = p._finish_step(step, t0)
            except Exception as exc:
                out[i] = exc
