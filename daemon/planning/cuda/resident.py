"""The host side of fast.cu's resident loop (``kernels/resident.cuh``).

A resident loop is one launch of ``plan_resident`` that serves the planning calls of one
planner until it is stopped or has been idle for ``IDLE_MS``. A call costs the host the
stores of its params and delta into the mailbox (page-locked host memory mapped into the
device) and of ``abi.MB_POST`` last; the loop writes the results back into the mapped I/O
buffer and sets the done word. While the user walks, a step pays no launch; a loop that ended
idle is launched again by the next call, so no other way to serve a fast call is needed.

The loop holds every SM (it polls), so only one runs per process (``_ACTIVE``), and any other
work that launches kernels on the device first stops it (``evict``). Copies do not need to:
the loop runs on its own non-blocking stream and touches no planner state between calls.

Races are settled by the device, not by the host's guess: a call posted just as a loop ends
idle is not lost; ``wait`` sees the stream idle with the done word unset and launches again,
and a new loop serves a posted call whose seq differs from the done word.
"""

from __future__ import annotations

import atexit
import contextlib
import time
from collections.abc import Callable

import cupy as cp
import numpy as np

from . import abi, device

assert abi.MB_POST % 2 == 0 and abi.MB_COUNT == abi.MB_POST + 1, "post and count: one store"
IDLE_MS = 200.0
"""How long a loop waits for the next call before it ends and frees the device: longer than
the gap between a walk's steps (sensing and inflation: ~1-5 ms at 400², tens of ms at 2000²,
where 50 ms let the loop end before ~1 % of the steps, each of which then paid a launch:
those were the p99 steps, scripts/profile_cuda_phases.py), short enough that a planner left
alone stops holding the GPU soon."""
NOT_READY = 600  # cudaErrorNotReady: the stream still has work
CHECK_S = 200e-6  # how often ``wait`` asks the driver whether the loop still runs

_ACTIVE: ResidentLoop | None = None


class ResidentLoop:
    """One planner's loop: ``launch(stream)`` queues ``plan_resident`` on ``stream`` with this
    loop's arguments; ``keep`` holds every buffer those arguments point to, so none is freed
    or reused while a launch may still run."""

    def __init__(
        self, launch: Callable[[cp.cuda.Stream], None], mail: np.ndarray, keep: tuple
    ) -> None:
        self._launch = launch
        self._mail = mail
        # (seq, delta length) as one 8-byte item: a memoryview's store is ~1 µs cheaper than
        # numpy's, cold; MB_POST is 8-byte aligned, so the store is one move.
        self._post = memoryview(mail).cast("B").cast("q")
        self._post_at = abi.MB_POST // 2
        self._keep = keep
        self.stream = cp.cuda.Stream(non_blocking=True)
        self.launches = 0  # how many times the loop was (re)started (statistics, tests)
        self._running = False  # a launch is queued that was not seen to end
        self._served_at = 0.0  # perf_counter when the last call was seen done

    def post(self, seq: int, n_delta: int) -> None:
        """Hand the loop the call whose params and delta are in the mailbox: ``seq`` is its
        params' seq, ``n_delta`` its delta's length. Starts the loop if none runs (any other
        planner's loop is stopped)."""
        if _ACTIVE is not self:
            evict()
        if self._running and time.perf_counter() - self._served_at > 0.5e-3 * IDLE_MS:
            self._ended()  # the loop may have ended idle: then start it now, not in wait
        # Last, as one 8-byte store: x86 makes the earlier stores visible first, and the loop
        # reads seq and length in one PCIe read, so it fetches params and delta together.
        self._post[self._post_at] = (n_delta << 32) | seq
        if not self._running:
            self._start()

    def _start(self) -> None:
        global _ACTIVE
        self._launch(self.stream)
        self._running = True
        self.launches += 1
        _ACTIVE = self

    def wait(self, io: memoryview, seq: int) -> None:
        """Until the loop has set ``io[abi.IO_DONE]`` to ``seq``. Spins; after
        ``device.SPIN_S`` each poll first yields the GIL (the daemon's event loop runs during
        long plans; a sleep of any length would add Linux's 50 µs timer slack to the wait).
        Every ``CHECK_S`` the stream is queried: a CUDA fault is raised as a cupy error, and a
        loop that ended before taking the call (idle) is started again, once."""
        at = abi.IO_DONE
        t0 = last = time.perf_counter()
        spins = 0
        restarted = False
        while io[at] != seq:
            spins += 1
            if spins & 31:
                continue
            now = time.perf_counter()
            if now - t0 > device.SPIN_S:
                time.sleep(0)  # a long call: let the daemon's other threads have the GIL
            if now - last < CHECK_S:
                continue
            last = now
            if not self._ended():
                continue
            if io[at] == seq:
                break
            if restarted:
                raise RuntimeError("the resident planning loop ended without serving a call")
            self._start()
            restarted = True
        self._served_at = time.perf_counter()

    def _ended(self) -> bool:
        """True when no launch of this loop runs; a CUDA error is raised."""
        status = cp.cuda.runtime.streamQuery(self.stream.ptr)
        if status == NOT_READY:
            return False
        if status != 0:
            self.stream.synchronize()  # raises the error as CUDARuntimeError
        self._running = False
        return True

    def stop(self) -> None:
        """End the loop and wait for it (it finishes no call: the host posts none while it
        stops one). A CUDA fault of the loop is raised here."""
        global _ACTIVE
        if _ACTIVE is self:
            _ACTIVE = None
        if not self._running:
            return
        self._mail[abi.MB_STOP] = 1
        try:
            self.stream.synchronize()
        finally:
            self._mail[abi.MB_STOP] = 0
            self._running = False


def active() -> ResidentLoop | None:
    """The loop started last and not stopped since (it may have ended idle)."""
    return _ACTIVE


def evict() -> None:
    """Stop the process's running loop, if any: call before any launch that needs SMs."""
    if _ACTIVE is not None:
        _ACTIVE.stop()


@atexit.register
def _stop_at_exit() -> None:
    with contextlib.suppress(Exception):  # the context may be gone already: nothing to free
        evict()
