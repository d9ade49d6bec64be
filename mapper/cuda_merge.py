"""``merge.merge_frame`` inside the frame's CUDA graph: the global map lives on the device.

On an H100 host at a camera's 30 fps every µs of host work on a frame's path costs 2-7 µs
(the core goes cold in the 33 ms between frames), and the numba merge was 123 µs of it cold.
Here the merge is one more kernel of the frame's graph (``kernels/merge_cells.cu``): it reads
the pass's counts and per-bin points where ``bin_pixels`` left them, updates the map kept on
the device (occupancy, log-odds, seen-at, the start map's fixed cells) and leaves only the
changed cells, compacted on the device in ``merge_frame``'s order, with the proximity's
figures; the graph's one read-back brings those back instead of the window's 42 kB of
counts. The kernel also resets the pass's counts for the next frame, so the graph has five
nodes instead of nine (each costs launch time on the host: 79 -> 89 µs cold for 7 -> 9).
The frame check's last two rules decide on the device whether the map is written
(``check_depth`` from the pass's own pixel count, ``check_motion`` worked out on the host
before the launch), so a refused frame leaves the map as it was, as on the CPU.

The host keeps its occupancy current (the changed cells are applied to it every frame: the
snapshot and the picture read it); log-odds and seen-at are copied back only when asked for
(``DeviceMap.pull``).
"""

from __future__ import annotations

from pathlib import Path

import cupy as cp
import cupyx
import numpy as np

KERNEL = Path(__file__).with_name("kernels") / "merge_cells.cu"
MERGE_THREADS = 512
"""The merge's one block (``merge_cells.cu``'s THREADS)."""
HEAD_INTS = 14
"""k, g, valid, present, committed, pad, then ahead, nearest, side, fwd as doubles."""
SPARE = 4096
"""Forgotten cells the graph's read-back brings beyond the window's: more (a whole room
forgotten in one second) are fetched by a second copy after the wait."""
_KERNEL: list[cp.RawKernel] = []


def merge_kernel() -> cp.RawKernel:
    """``merge_cells``, compiled once, without fused multiply-adds (the CPU's rounding)."""
    if not _KERNEL:
        mod = cp.RawModule(code=KERNEL.read_text(), options=("-std=c++17", "--fmad=false"))
        _KERNEL.append(mod.get_function("merge_cells"))
    return _KERNEL[0]


class DeviceMap:
    """The global map on the device, for one mapper at a time: ``attach`` uploads a mapper's
    host arrays when they are not the ones it holds, into the same buffers (the captured
    graphs point at them)."""

    def __init__(self, shape: tuple[int, int]) -> None:
        self.shape = shape
        self.occ = cp.empty(shape, cp.uint8)
        self.lo = cp.empty(shape, cp.float32)
        self.seen = cp.empty(shape, cp.float64)
        self.fixed = cp.empty(shape, cp.uint8)
        self._host: tuple = ()

    def attach(self, occupancy: np.ndarray, logodds: np.ndarray, seen_at: np.ndarray,
               fixed: np.ndarray) -> None:  # fmt: skip
        held = self._host
        if (held and held[0] is occupancy and held[1] is logodds and held[2] is seen_at
                and held[3] is fixed):  # fmt: skip
            return  # every frame of the same mapper: no generator on the frame's path
        self.occ.set(np.ascontiguousarray(occupancy, np.uint8))
        self.lo.set(np.ascontiguousarray(logodds, np.float32))
        self.seen.set(np.ascontiguousarray(seen_at, np.float64))
        self.fixed.set(np.ascontiguousarray(fixed, np.uint8))
        cp.cuda.Device().synchronize()  # the passes' streams read these next
        self._host = (occupancy, logodds, seen_at, fixed)

    def pull(self, logodds: np.ndarray, seen_at: np.ndarray) -> None:
        """The device's log-odds and seen-at into the host's arrays, in place."""
        logodds[...] = self.lo.get()
        seen_at[...] = self.seen.get()


class MergeTail:
    """One pass's merge: its scratch and output on the device, their page-locked twin, and
    the kernel and the read-back captured at the end of the pass's graph."""

    def __init__(self, side: int, dmap: DeviceMap) -> None:
        n, m = side * side, dmap.shape[0] * dmap.shape[1]
        self.cap = n + m
        self.scratch = cp.empty(3 * n, cp.uint8)
        # The header, then one word a changed cell: flat index << 2 | value.
        self.head = cp.empty(HEAD_INTS + self.cap, cp.int32)
        self.copied = min(self.cap, n + SPARE)
        self.host_head = cupyx.empty_pinned(HEAD_INTS + self.copied, np.int32)
        self.ints = self.host_head[:5]
        self.doubles = self.host_head[6:HEAD_INTS].view(np.float64)
        self.words = self.host_head[HEAD_INTS:].view(np.uint32)
        self.dmap = dmap
        self.side = side

    def capture(self, stream: cp.cuda.Stream, out: cp.ndarray, params: cp.ndarray, bins: int,
                hit_key: cp.ndarray, far_key: cp.ndarray) -> None:  # fmt: skip
        """The kernel and the read-back, on ``stream`` while it captures; the kernel also
        resets ``out``'s counts and the bin keys for the pass's next frame."""
        d, rt = self.dmap, cp.cuda.runtime
        merge_kernel()(
            (1,), (MERGE_THREADS,),
            (out, params, np.int32(self.side), np.int32(bins), np.int32(d.shape[0]),
             np.int32(d.shape[1]), d.occ, d.lo, d.seen, d.fixed, self.scratch, self.head,
             hit_key, far_key), stream=stream,
        )  # fmt: skip
        rt.memcpyAsync(self.host_head.ctypes.data, self.head.data.ptr, self.host_head.nbytes,
                       rt.memcpyDeviceToHost, stream.ptr)  # fmt: skip

    def result(self) -> tuple[np.ndarray, np.ndarray, int, int, bool, tuple[float, ...]]:
        """After the wait: the changed cells and values, valid and present pixel counts,
        whether the map was written, and (ahead, nearest, side, fwd), NaN: none."""
        k, g, valid, present, committed = self.ints.tolist()
        m = k + g
        if m <= self.copied:
            words = self.words[:m]
        else:  # more forgotten than the graph brings: the rest in a second copy
            words = self.head[HEAD_INTS : HEAD_INTS + m].get().view(np.uint32)
        cells = (words >> 2).astype(np.int64)
        values = (words & 3).astype(np.uint8)
        return cells, values, valid, present, bool(committed), tuple(self.doubles.tolist())
