"""How a ``fast`` call reaches the device (``CudaPlanner`` mixes this in).

Three ways, fastest first: posted to the resident loop (``cuda_resident.py``, the default),
launched as a replayed CUDA graph (``resident=False``), or launched directly
(``use_graph=False``). Each way fills the same params words first and ends the same way: the
call sets the done word in the mapped I/O buffer, which the host polls, and the host reads
the call's result words (``RESULT_WORDS``) in one unpack.
"""

from __future__ import annotations

import struct
from collections.abc import Callable

import cupy as cp
import numpy as np

from . import cuda_kernels as ck
from . import cuda_resident

# Compiled once: struct's module functions parse the format string at every call, and these
# run at every step.
PARAMS_WORDS = struct.Struct("5i")  # fast.cu's params [ndelta, mode, start, goal, seq]
RESULT_WORDS = struct.Struct(
    f"<{ck.CTRL_READ}I{4 * (ck.IO_REJECT - ck.CTRL_READ)}xI{4 * (ck.IO_PATH - ck.IO_REJECT - 1)}x2i"
)
"""What a finished call left before its path, in one read: the ctrl words it copies back (the
statistics), the rejection bits of its delta (resident loop), the fused path's count and
status. One unpack after the done word instead of three reads: after the walk's other work
each read of the mapped buffer from Python costs 1-3 µs (BENCHMARKS.md)."""
R_REJECT, R_COUNT, R_STATUS = ck.CTRL_READ, ck.CTRL_READ + 1, ck.CTRL_READ + 2


class FastLaunch:
    """The fast call's launch over ``CudaPlanner``'s buffers (see ``CudaPlanner._allocate``)."""

    _shape: tuple[int, int]
    _goal: tuple[int, int]
    _seq: int
    _stage: ck.Pinned
    _stage_views: tuple[np.ndarray, ...]
    _io_host: ck.Pinned
    _params: cp.ndarray
    _g: cp.ndarray
    _blocked_d: cp.ndarray
    _raised: cp.ndarray
    _flags: cp.ndarray
    _ctrl: cp.ndarray
    _exits: cp.ndarray
    _segs: cp.ndarray
    _path_cap: int
    _result: tuple[int, ...]
    _blocks: int
    _defines: tuple[str, ...]
    _graph: cp.cuda.graph.Graph | None
    _loop: cuda_resident.ResidentLoop | None
    resident: bool
    use_graph: bool
    while_waiting: Callable[[], None] | None
    sweeps: int
    raised_cells: int
    tiles: int
    exit_tiles: int

    def _k_fast(self) -> cp.RawKernel:
        return ck.kernel("fast", "plan_persistent", self._defines)

    def _k_loop(self) -> cp.RawKernel:
        return ck.kernel("fast", "plan_resident", self._defines)

    def _call_fast(
        self, eds: bool, cells: np.ndarray | None, blocked: np.ndarray | None, start: int = -1
    ) -> None:
        """One fast call (lock held), the delta ``cells`` / ``blocked`` (none: ``cells`` is
        None); the call's result words end in ``_result``. Posted to the resident loop
        (``_call_resident``) or launched: the delta encoded and checked here, then params and
        delta copied up with the launch, and the done word polled."""
        if self.resident:
            self._call_resident(eds, cells, blocked, start)
            return
        n = 0 if cells is None else self._stage_delta(cells, blocked)
        self._launch_fast(eds, n, start)
        if self.while_waiting is not None:
            self.while_waiting()
        ck.wait_word(self._io_host.view, ck.IO_DONE, self._seq)
        self._result = RESULT_WORDS.unpack_from(self._io_host.view)

    def _call_resident(
        self,
        eds: bool,
        cells: np.ndarray | None,
        blocked: np.ndarray | None,
        start: int,
        again: bool = False,
    ) -> None:
        """A call posted to the resident loop: the delta raw into the mailbox, the params, the
        post, the wait, the result words. Every step of a walk runs this, so it does its
        staging itself and handles its rare cases at the end (a cold Python call or numpy access
        costs ~1 µs after the walk's other work; BENCHMARKS.md). The loop checks the delta:
        a cell outside the map is an IndexError (nothing applied); cells out of order (a cell
        twice, say) are sorted here, each keeping its last value, and posted ``again``."""
        n = 0
        if cells is not None:
            # Cells as int64, then a byte per cell (resident.cuh, take_delta): two numpy
            # copies, which cast and broadcast as needed.
            cells = cells if isinstance(cells, np.ndarray) else np.asarray(cells)
            if cells.ndim != 1:
                cells = cells.ravel()
            n = cells.size
            # 8 + 1 bytes a cell after the params, in whole 16-byte chunks (the loop reads the
            # stage in chunks).
            words = ck.PARAMS + 4 * ((9 * n + 15) // 16)
            if words > self._stage.count or ck.PARAMS + n > self._params.size:
                self._grow_stage(words, n)
            if self._stage_views[0] is not self._stage.array:  # views of the stage as it is now
                stage = self._stage.array
                self._stage_views = (stage, stage.view(np.int64), stage.view(np.uint8))
            _, as_int64, as_bytes = self._stage_views
            as_int64[ck.PARAMS // 2 : ck.PARAMS // 2 + n] = cells
            at = 4 * ck.PARAMS + 8 * n
            as_bytes[at : at + n] = blocked
        loop = self._loop  # after staging: a stage that had to grow stopped the loop
        if loop is None:
            loop = self._loop = self._new_loop()
        seq = self._pack_params(eds, n, start)
        loop.post(seq, n)
        if self.while_waiting is not None and not again:
            self.while_waiting()
        io = self._io_host.view
        loop.wait(io, seq)
        self._result = result = RESULT_WORDS.unpack_from(io)
        reject = result[R_REJECT]
        if not reject:
            return
        if reject & ck.REJECT_RANGE:
            h, w = self._shape
            raise IndexError(f"a cell index is outside the map of {h * w} cells")
        if again or cells is None or blocked is None:
            raise RuntimeError("the resident loop refused a sorted delta")
        cells, blocked = ck.unique_last(cells, blocked)
        self._call_resident(eds, cells, blocked, start, again=True)

    def _pack_params(self, eds: bool, n_delta: int, start: int) -> int:
        """fast.cu's params words [ndelta, mode, start, goal, seq] into the stage, for the next
        call's new seq, which it returns."""
        self._seq = seq = self._seq % 0x7FFFFFFF + 1
        goal = self._goal[0] * self._shape[1] + self._goal[1]
        PARAMS_WORDS.pack_into(self._stage.view, 0, n_delta, int(eds), start, goal, seq)
        return seq

    def _read_fast_stats(self) -> tuple[int, int]:
        st = self._result
        self.sweeps, self.raised_cells = st[ck.C_SWEEPS], st[ck.C_RAISED]
        self.tiles, self.exit_tiles = st[ck.C_TILES], st[ck.C_EXITS]
        return st[ck.C_ROUNDS], self.raised_cells + st[ck.C_CHANGED]

    def _launch_fast(self, eds: bool, n_delta: int, start: int = -1) -> None:
        """Launch one fast call: params and delta up, the launch (repair; with ``start`` >= 0,
        a flat cell, the path from it too), which writes its results into the mapped I/O
        buffer. With ``use_graph`` the copy and the launch replay as one captured CUDA graph:
        one call from Python instead of two, one of them with 12 kernel arguments packed by
        CuPy."""
        self._pack_params(eds, n_delta, start)
        cuda_resident.evict()
        if not self.use_graph:
            self._queue_fast(ck.PARAMS + n_delta)
            return
        if self._graph is None:
            self._graph = self._capture()
        if n_delta > ck.GRAPH_DELTA:  # the graph's own copy takes the first GRAPH_DELTA cells
            rest = ck.PARAMS + ck.GRAPH_DELTA
            self._stage.to_device(self._params, n_delta - ck.GRAPH_DELTA, offset=rest)
        self._graph.launch()

    def _queue_fast(self, up: int) -> None:
        h, w = self._shape
        self._stage.to_device(self._params, up)
        self._k_fast()(
            (self._blocks,), (ck.THREADS,),
            (self._g, self._blocked_d, self._raised, self._params, self._flags, self._ctrl,
             np.int32(h), np.int32(w), self._exits, self._segs,
             np.uint64(self._io_host.device_ptr), np.int32(self._path_cap)),
        )  # fmt: skip

    def _new_loop(self) -> cuda_resident.ResidentLoop:
        """The resident loop over this planner's buffers as they are now."""
        h, w = self._shape
        args = (self._g, self._blocked_d, self._raised, self._params, self._flags, self._ctrl,
                np.int32(h), np.int32(w), self._exits, self._segs,
                np.uint64(self._io_host.device_ptr), np.int32(self._path_cap),
                np.uint64(self._stage.device_ptr))  # fmt: skip
        k = self._k_loop()
        blocks = self._blocks

        def launch(stream: cp.cuda.Stream) -> None:
            idle_us = np.uint32(cuda_resident.IDLE_MS * 1000)
            k((blocks,), (ck.THREADS,), (*args, idle_us), stream=stream)

        # The loop keeps the mapped buffers' memory too: a Pinned that grows lets go of its own.
        keep = (args, self._io_host.memory, self._stage.memory)
        return cuda_resident.ResidentLoop(launch, self._stage.array, keep)

    def _capture(self) -> cp.cuda.graph.Graph:
        """The fast call as a CUDA graph (it holds the buffers' addresses, so any reallocation
        sets ``_graph`` to None and the next call captures again)."""
        self._k_fast()  # compiled and loaded before the capture
        side = cp.cuda.Stream(non_blocking=True)
        with side:
            side.begin_capture()
            try:
                self._queue_fast(ck.PARAMS + ck.GRAPH_DELTA)
            finally:
                graph = side.end_capture()
        return graph
