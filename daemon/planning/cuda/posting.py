"""Walking steps posted to the device's resident loop: one alone, or several side by side.

``post_steps`` is what a post runs; ``update_and_path`` reaches it through ``STEPS``, the
process's combiner (``combine.py``): a step that finds the device free is posted alone at
once, and steps that other threads call while a post is in flight go together as the next
post (``ResidentLoop.post_batch``: each on a group of the loop's blocks). ``batch.py``'s
``step_many`` posts a caller's own batch through it too.
"""

from __future__ import annotations

import functools
from typing import Any

import numpy as np

from . import abi, device, resident
from .combine import Combiner

Post = tuple[Any, np.ndarray, np.ndarray, tuple[int, int], float]
"""(fast ``CudaPlanner``, cells, blocked, start, t0): one step, ``t0`` its caller's clock at
the call (its statistics' ms count from there, the wait for the post included)."""

GROUP_MIN = 8
"""Blocks a batched call gets at least: a post holds at most the loop's blocks / GROUP_MIN
calls. A post ends when its slowest call does, and a call that recomputes its field (the
cut-over) or all its exits on one block takes milliseconds."""


@functools.cache
def batch_size() -> int:
    """Calls a post holds: the device's resident loop blocks / ``GROUP_MIN`` (one device per
    process: asked once)."""
    blocks = device.resident_blocks(device.kernel("fast", "plan_users"))
    return max(1, min(abi.BATCH_MAX, blocks // GROUP_MIN))


def post_one(step: Post) -> Any:
    """One step posted alone, the call as before batches, on every block of the loop: its
    ``(UpdateStats, path)``, or its exception raised. What a walking step that finds the
    device free runs (``STEPS``'s ``solo``): the loop's own post and wait, not ``Slot``'s,
    and no lists, which cost a frame or an allocation each at every step."""
    p, cells, blocked, start, t0 = step
    with device.DEVICE_LOCK:
        staged = p._stage_step(cells, blocked, start)
        slot = p._loop
        loop = slot.loop
        loop.post(slot.index, staged[2])
        loop.wait(p._io_host.view, staged[1], STEPS.contended)
        return p._finish_step(staged, t0)


def post_steps(steps: list[Post]) -> list[Any]:
    """Each step's ``(UpdateStats, path)`` or the exception it raised, in order (at most
    ``abi.BATCH_MAX`` steps, each planner once)."""
    if len(steps) == 1:
        try:
            return [post_one(steps[0])]
        except Exception as exc:  # the caller's own: raised in its thread
            return [exc]
    out: list[Any] = [None] * len(steps)
    with device.DEVICE_LOCK:
        staged: list[tuple[int, Any, tuple]] = []
        for i, (p, cells, blocked, start, _) in enumerate(steps):
            try:
                staged.append((i, p, p._stage_step(cells, blocked, start)))
            except Exception as exc:
                out[i] = exc
        if not staged:
            return out
        # Staging may stop the loop (a buffer that grows, a table that grows) or attach a
        # planner: only once every step is staged are the slots final.
        loop = resident.shared()
        calls = np.empty((len(staged), 2), dtype=np.int32)
        for row, (_, p, step) in enumerate(staged):
            slot = p._loop
            assert slot is not None and slot.loop is loop, "one loop per process"
            calls[row] = slot.index, step[2]
        loop.post_batch(calls)
        share = STEPS.contended
        for i, p, step in staged:
            try:
                loop.wait(p._io_host.view, step[1], share)
            except Exception as exc:  # a CUDA fault: every step has it
                out[i] = exc
        for i, p, step in staged:
            if out[i] is not None:
                continue
            try:
                out[i] = p._finish_step(step, steps[i][4])
            except Exception as exc:
                out[i] = exc
    return out


STEPS: Combiner[Post] = Combiner(
    post_steps, batch_size, key=lambda step: id(step[0]), solo=post_one
)
"""The process's walking steps, combined across threads (one device, one loop a process)."""
