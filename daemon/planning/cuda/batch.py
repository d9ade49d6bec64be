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
``update_and_path`` does. An EDS step that needs no repair (``deferred_blocks.py``: its new
obstacles all miss the user's path) is answered on the host and never posted; the others post
their pending blocks merged with their delta; the blocks it deferred are posted between steps,
every user's together (``between_steps_many``).
"""

from __future__ import annotations

import time
from collections.abc import Sequence
from typing import Any

import numpy as np

from ..deferred_blocks import DeferredBlocks
from . import abi
from .planner import CudaPlanner
from .posting import batch_size, post_steps
from .small_grids import SmallGridsOnCpu

Step = tuple[Any, np.ndarray, np.ndarray, tuple[int, int]]
"""(planner, cells, blocked, start): one user's ``update_and_path``."""


def step_many(steps: Sequence[Step], max_batch: int | None = None) -> list[Any]:
    """Every step's ``(UpdateStats, path)``, or the exception it raised, in order. The fast
    cuda planners' steps go to the device in posts of up to ``max_batch`` calls (default
    ``batch_size()``), one after another."""
    if len({id(step[0]) for step in steps}) != len(steps):
        raise ValueError("a batch holds each planner once")
    out: list[Any] = [None] * len(steps)
    fast: list[int] = []
    posts = []
    keeps: dict[int, DeferredBlocks] = {}
    t0 = time.perf_counter()
    for i, (p, cells, blocked, start) in enumerate(steps):
        if isinstance(p, DeferredBlocks):
            done = p.deferred(cells, blocked, start)
            if done is not None:  # no repair needed: nothing to post
                out[i] = done
                continue
            try:
                cells, blocked = p.merged(cells, blocked)
            except Exception as exc:
                out[i] = exc
                continue
            keeps[i], p = p, p.inner
        own = p
        if isinstance(p, SmallGridsOnCpu):  # the cuda backend's EDS: which one serves the map
            p = p._serving
        if isinstance(p, CudaPlanner) and p.variant == "fast":
            fast.append(i)
            posts.append((p, cells, blocked, start, t0))
            continue
        try:
            out[i] = own.update_and_path(cells, blocked, start)
        except Exception as exc:  # one user's failure is that user's result
            out[i] = exc
    size = min(max_batch or batch_size(), abi.BATCH_MAX)
    for at in range(0, len(fast), size):
        for i, res in zip(fast[at : at + size], post_steps(posts[at : at + size]), strict=True):
            out[i] = res
    for i, wrapper in keeps.items():  # each repaired step's path is its planner's new P
        if not isinstance(out[i], BaseException):
            wrapper.kept(out[i][1])
    return out


def between_steps_many(planners: Sequence[Any], max_batch: int | None = None) -> list[Any]:
    """Every planner's work for between steps (``GlobalPlanner.between_steps``), the deferred
    blocks of the cuda backend's EDS posted together (``step_many``) rather than one round trip
    each. The exception a planner's work raised, in its place, else None; a planner whose
    deferred blocks failed must plan afresh (``DeferredBlocks.pending_step``)."""
    out: list[Any] = [None] * len(planners)
    steps: list[Step] = []
    where: list[int] = []
    for i, p in enumerate(planners):
        try:
            step = p.pending_step() if isinstance(p, DeferredBlocks) else None
            if step is None:
                p.between_steps()
                continue
        except Exception as exc:  # one user's failure is that user's result
            out[i] = exc
            continue
        steps.append(step)
        where.append(i)
    for i, res in zip(where, step_many(steps, max_batch), strict=True):
        if isinstance(res, BaseException):
            out[i] = res
    return out
