"""The host side of fast.cu's resident loop (``kernels/resident.cuh``, ``plan_users``).

A resident loop is one launch that serves the planning calls of every fast planner of the
process until it is stopped or has been idle for ``IDLE_MS``. A planner attaches once per set
of buffers (``ResidentLoop.attach``: a slot in the loop's table, in device memory); a call
costs the host the stores of its params and delta into the planner's mailbox (page-locked
host memory mapped into the device), then of the slot and the post into the loop's box; the
loop writes the results back into the planner's mapped I/O buffer and sets its done word.
While users walk, a step pays no launch, whoever stepped before; a loop that ended idle is
launched again by the next call, so no other way to serve a fast call is needed.

Before, each planner had a loop of its own, and a call of another planner stopped it and
launched its own: with 4 or 16 users stepping in turn a step cost ~0.25 ms and single steps
stalled ~45 ms (issue 28, H100). One loop for all removes the stop and the launch.

``post_batch`` hands the loop several planners' calls in one post (``batch.py``): the loop
serves them side by side, each on a group of its blocks, where one call at a time held every
SM for a few tiles' work and one host thread topped out at ~9,200 steps/s at 400².

The loop holds every SM (it polls), so only one runs per process (``_ACTIVE``), and any other
work that launches kernels on the device first stops it (``evict``). Copies do not need to:
the loop runs on its own non-blocking stream and touches no planner state between calls.

Races are settled by the device, not by the host's guess: a call posted just as a loop ends
idle is not lost; ``wait`` sees the stream idle with the done word unset and launches again,
and a new loop serves a post whose generation differs from the one the last loop served.
"""

from __future__ import annotations

import atexit
import contextlib
import time
from collections.abc import Callable

import cupy as cp
import numpy as np

from . import abi, device

assert abi.BOX_POST % 2 == 0 and abi.BOX_COUNT == abi.BOX_POST + 1, "post and count: one store"
IDLE_MS = 200.0
"""How long a loop waits for the next call before it ends and frees the device: longer than
the gap between a walk's steps (sensing and inflation: ~1-5 ms at 400², tens of ms at 2000²,
where 50 ms let the loop end before ~1 % of the steps, each of which then paid a launch:
those were the p99 steps, scripts/profile_cuda_phases.py), short enough that a planner left
alone stops holding the GPU soon."""
NOT_READY = 600  # cudaErrorNotReady: the stream still has work
CHECK_S = 200e-6  # how often ``wait`` asks the driver whether the loop still runs

SLOTS = 64
"""Slots of a new loop's table; it doubles when a planner more attaches (the loop is stopped:
the table is an argument of its launch)."""

_ACTIVE: ResidentLoop | None = None
_SHARED: ResidentLoop | None = None


class Slot:
    """One planner's place in the device's loop: ``post`` and ``wait`` its calls; ``stop``
    gives the slot back (the loop keeps running for the others)."""

    __slots__ = ("_release", "index", "loop")

    def __init__(self, loop: ResidentLoop, index: int, release: Callable[[], None]) -> None:
        self.loop, self.index, self._release = loop, index, release

    def post(self, seq: int, n_delta: int) -> None:
        """Hand the loop the call whose params (``seq`` among them) and delta of ``n_delta``
        cells are in this planner's mailbox."""
        self.loop.post(self.index, n_delta)

    def wait(self, io: memoryview, seq: int, share: bool = False) -> None:
        self.loop.wait(io, seq, share)

    def stop(self) -> None:
        self._release()

    @property
    def launches(self) -> int:
        return self.loop.launches


class ResidentLoop:
    """The device's loop (``kernels/resident.cuh``, ``plan_users``): one launch serves every
    attached planner's calls. ``attach(words, keep)`` gives a planner a slot: ``words`` are
    its descriptor (``abi.SLOT_*``), ``keep`` the buffers they point to, held until the slot
    is given back. Calls are serialised by the caller (``device.DEVICE_LOCK``): one call, or
    one batch of calls of different slots (``post_batch``), is posted, then waited for."""

    def __init__(self, launch: Callable[..., None] | None = None) -> None:
        # launch(stream, table, ctrl, box_ptr): queues the loop; a stand-in in host tests.
        self._launch = launch or _launch_users
        self._box = device.Pinned(abi.BOX_QUEUE + 2 * abi.BATCH_MAX, np.int32, mapped=True)
        self._mail = self._box.array
        # (generation, delta length) as one 8-byte item: a memoryview's store is ~1 µs cheaper
        # than numpy's, cold; BOX_POST is 8-byte aligned, so the store is one move.
        self._post = memoryview(self._mail).cast("B").cast("q")
        self._words = self._box.view
        self._queue = self._mail[abi.BOX_QUEUE :].reshape(abi.BATCH_MAX, 2)
        self._ctrl = cp.zeros(abi.C_QUEUE + abi.BATCH_RING * abi.BATCH_WORDS, dtype=np.uint32)
        self._table = cp.zeros((SLOTS, abi.SLOT_WORDS), dtype=np.uint64)
        self._keep: dict[int, tuple] = {}
        self._dead: list[tuple] = []  # given back while the loop ran: freed at its stop
        self._gen = 0
        self.stream = cp.cuda.Stream(non_blocking=True)
        self.launches = 0  # how many times the loop was (re)started (statistics, tests)
        self._running = False  # a launch is queued that was not seen to end
        self._served_at = 0.0  # perf_counter when the last call was seen done

    @property
    def attached(self) -> int:
        return len(self._keep)

    def attach(self, words: tuple[int, ...], keep: tuple) -> Slot:
        """A slot for a planner whose buffers ``words`` describe (``abi.SLOT_*`` order)."""
        index = next(i for i in range(len(self._keep) + 1) if i not in self._keep)
        if index >= self._table.shape[0]:
            self.stop()  # the table is the launch's argument
            grown = cp.zeros((2 * self._table.shape[0], abi.SLOT_WORDS), dtype=np.uint64)
            grown[: self._table.shape[0]] = self._table
            self._table = grown
        row = np.zeros(abi.SLOT_WORDS, dtype=np.uint64)
        row[: len(words)] = words
        # A copy on the caller's stream, which a running loop's non-blocking stream does not
        # wait for; done before the slot's first post (blocks read it from L2: __ldcg).
        self._table[index].set(row)
        device.synchronize()
        self._keep[index] = keep

        def release() -> None:
            # Between calls no block touches a planner's buffers: its call's last barrier came
            # before the done word the host waited for. Only this attachment's: the index may
            # serve another planner by the time a late finalizer runs.
            # The buffers themselves are let go only once the loop is stopped (``stop``): a
            # page-locked free may synchronise with the device (the CUDA guide lists
            # page-locked allocation among the implicit synchronisations), which a polling
            # loop would hold up until it ends idle.
            if self._keep.get(index) is keep:
                self._dead.append(self._keep.pop(index))

        return Slot(self, index, release)

    def post(self, slot: int, n_delta: int) -> None:
        """Hand the loop ``slot``'s call (params and delta in the slot's mailbox, ``n_delta``
        cells). Starts the loop if none runs."""
        # _before_post's checks written out: every walking step posts here.
        if _ACTIVE is not self:
            evict()
        if self._running and time.perf_counter() - self._served_at > 0.5e-3 * IDLE_MS:
            self._ended()
        self._words[abi.BOX_SLOT] = slot
        self._gen = gen = self._gen % 0x7FFFFFFF + 1
        # Last, as one 8-byte store: x86 makes the earlier stores visible first, and the loop
        # reads slot, generation and length in one PCIe read.
        self._post[abi.BOX_POST // 2] = (n_delta << 32) | gen
        if not self._running:
            self._start()

    def post_batch(self, calls: np.ndarray) -> None:
        """Hand the loop several slots' calls at once, served side by side (``calls``: one
        (slot, delta length) row each, at most ``abi.BATCH_MAX``, no slot twice). One call
        goes as ``post`` does: its group is the whole device, as fast as before batches."""
        k = len(calls)
        if k == 1:
            self.post(int(calls[0, 0]), int(calls[0, 1]))
            return
        if not 1 < k <= abi.BATCH_MAX:
            raise ValueError(f"a batch holds 1 to {abi.BATCH_MAX} calls, not {k}")
        self._before_post()
        self._queue[:k] = calls
        self._words[abi.BOX_SLOT] = -k
        self._gen = gen = self._gen % 0x7FFFFFFF + 1
        self._post[abi.BOX_POST // 2] = gen  # after the queue (x86 keeps the stores' order)
        if not self._running:
            self._start()

    def _before_post(self) -> None:
        if _ACTIVE is not self:
            evict()
        if self._running and time.perf_counter() - self._served_at > 0.5e-3 * IDLE_MS:
            self._ended()  # the loop may have ended idle: then start it now, not in wait

    def _start(self) -> None:
        global _ACTIVE
        self._launch(self.stream, self._table, self._ctrl, self._box.device_ptr)
        self._running = True
        self.launches += 1
        _ACTIVE = self

    def wait(self, io: memoryview, seq: int, share: bool = False) -> None:
        """Until the loop has set ``io[abi.IO_DONE]`` to ``seq``. Spins; after
        ``device.SPIN_S`` each poll first yields the GIL (the daemon's event loop runs during
        long plans; a sleep of any length would add Linux's 50 µs timer slack to the wait).
        ``share``: every 256th spin yields too, so that threads whose steps fall due meanwhile
        can queue them for the next post (``combine.py``); for a thread stepping alone the
        ~50-70 µs a sleep(0) costs is not paid (device run 7: 0.113 ms a step against 0.060).
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
            if now - t0 > device.SPIN_S or (share and not spins & 255):
                time.sleep(0)  # a long call, or callers waiting: let other threads have the GIL
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
            self._dead.clear()
            return
        self._mail[abi.BOX_STOP] = 1
        try:
            self.stream.synchronize()
        finally:
            self._mail[abi.BOX_STOP] = 0
            self._running = False
        self._dead.clear()


def shared() -> ResidentLoop:
    """The process's loop (one device per process: ``device.DEVICE_LOCK`` serialises its
    calls); made at first use."""
    global _SHARED
    if _SHARED is None:
        _SHARED = ResidentLoop()
    return _SHARED


def _launch_users(stream: cp.cuda.Stream, table: cp.ndarray, ctrl: cp.ndarray, box: int) -> None:
    k = device.kernel("fast", "plan_users")
    blocks = device.resident_blocks(k)  # every block resident at once: the barriers spin
    idle_us = np.uint32(IDLE_MS * 1000)
    k((blocks,), (abi.THREADS,), (table, ctrl, np.uint64(box), idle_us), stream=stream)


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
