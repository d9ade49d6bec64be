"""How a ``fast`` call reaches the device (``CudaPlanner`` mixes this in).

Three ways, fastest first: posted to the resident loop (``cuda_resident.py``, the default),
launched as a replayed CUDA graph (``resident=False``), or launched directly
(``use_graph=False``). Each way fills the same params words first and ends the same way: the
call sets the done word in the mapped I/O buffer, which ``_wait_fast`` polls.
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
CTRL_WORDS = struct.Struct(f"{ck.CTRL_READ}I")  # the ctrl words the call copies back


class FastLaunch:
    """The fast call's launch over ``CudaPlanner``'s buffers (see ``CudaPlanner._allocate``)."""

    _shape: tuple[int, int]
    _goal: tuple[int, int]
    _seq: int
    _stage: ck.Pinned
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
        """One fast call (lock held): stage the delta (none: ``cells`` is None), launch or
        post, wait. The resident loop refuses cells out of order (a cell twice, say): they are
        sorted on the host, each cell keeping its last value, and posted again."""
        n = 0 if cells is None else self._stage_delta(cells, blocked)
        self._launch_fast(eds, n, start)
        if self.while_waiting is not None:
            self.while_waiting()
        if self._wait_fast():
            return
        assert cells is not None and blocked is not None  # an empty delta is in order
        cells, blocked = ck.unique_last(cells, blocked)
        self._launch_fast(eds, self._stage_delta(cells, blocked), start)
        if not self._wait_fast():
            raise RuntimeError("the resident loop refused a sorted delta")

    def _wait_fast(self) -> bool:
        """Wait for the last fast call: fast.cu's last block sets the done word last. False if
        the resident loop refused its delta as out of order; IndexError (nothing applied) if a
        cell lies outside the map."""
        io = self._io_host.array
        if self._loop is None:
            ck.wait_word(io, ck.IO_DONE, self._seq)
            return True
        self._loop.wait(io, self._seq)
        reject = int(io[ck.IO_REJECT])
        if reject & ck.REJECT_RANGE:
            h, w = self._shape
            raise IndexError(f"a cell index is outside the map of {h * w} cells")
        return not reject

    def _read_fast_stats(self) -> tuple[int, int]:
        st = CTRL_WORDS.unpack_from(self._io_host.array)
        self.sweeps, self.raised_cells = st[ck.C_SWEEPS], st[ck.C_RAISED]
        self.tiles, self.exit_tiles = st[ck.C_TILES], st[ck.C_EXITS]
        return st[ck.C_ROUNDS], self.raised_cells + st[ck.C_CHANGED]

    def _launch_fast(self, eds: bool, n_delta: int, start: int = -1) -> None:
        """Queue one fast call: params and delta up, the launch (repair; with ``start`` >= 0, a
        flat cell, the path from it too), which writes its results into the mapped I/O
        buffer; ``_wait_fast`` waits for them. With ``use_graph`` the copy and the launch
        replay as one captured CUDA graph: one call from Python instead of two, one of them
        with 12 kernel arguments packed by CuPy."""
        self._seq = self._seq % 0x7FFFFFFF + 1
        goal = self._goal[0] * self._shape[1] + self._goal[1]
        # fast.cu's params [ndelta, mode, start, goal, seq]: one call, not five numpy stores.
        PARAMS_WORDS.pack_into(self._stage.array, 0, n_delta, int(eds), start, goal, self._seq)
        if self.resident:
            if self._loop is None:
                self._loop = self._new_loop()
            self._loop.post(self._seq, n_delta)
            return
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
