"""The CUDA side of the cuda backend: sources, compilation, launches and host transfers.

CUDA C lives in ``kernels/*.cu`` (and ``*.cuh``) and is compiled once per process and option
set (cupy also keeps the binaries in its on-disk cache). Everything here is thin: it sizes
launches, moves bytes through pinned host buffers (so a transfer is one asynchronous copy on
the stream and one synchronisation, with no pageable staging) and leaves the algorithms to
the kernels.
"""

from __future__ import annotations

import functools
import math
import threading
from pathlib import Path

import cupy as cp
import numpy as np

KERNELS = Path(__file__).with_name("kernels")
TILE = 32
THREADS = 1024

# ctrl slots of fast.cu read back after each call: C_BAR (the barrier count the next launch
# starts from) and the statistics C_EXITS .. C_CHANGED.
CTRL_READ = 13
IO_PATH = 64
P_STAMPS = 48  # fast.cu -DPROFILE: 8 phase stamps of the global timer
PARAMS = 8
"""fast.cu's params words (ndelta, mode, start, goal, ...) before the delta in a call's stage."""
GRAPH_DELTA = 1024  # delta cells the captured call copies up itself (more: one copy before)
GRAPH_PATH = 2048  # path cells it copies back with the ctrl words (more: one copy after)
"""fast.cu's 64 ctrl words, then the path: where the path starts in the planner's I/O buffer."""
C_BAR, C_EXITS, C_ROUNDS, C_TILES, C_SWEEPS, C_RAISED, C_CHANGED = 0, 7, 8, 9, 10, 11, 12

DEVICE_LOCK = threading.Lock()
"""One planning call on the device at a time: the persistent kernel's grid barrier needs every
one of its blocks resident, which a second concurrent launch could prevent."""


@functools.cache
def module(name: str, defines: tuple[str, ...] = ()) -> cp.RawModule:
    """``kernels/<name>.cu`` compiled with ``-D`` ``defines`` (cached for the process)."""
    code = (KERNELS / f"{name}.cu").read_text()
    # NVRTC compiles a string: name the folder so `#include "tile_scans.cuh"` resolves.
    options = ("--std=c++17", f"-I{KERNELS}", *(f"-D{d}" for d in defines))
    return cp.RawModule(code=code, options=options)


@functools.cache
def kernel(name: str, function: str, defines: tuple[str, ...] = ()) -> cp.RawKernel:
    return module(name, defines).get_function(function)


def resident_blocks(k: cp.RawKernel, threads: int = THREADS) -> int:
    """Blocks of ``k`` that fit on the device at once (registers, threads, shared memory)."""
    dev = cp.cuda.Device()
    attrs = dev.attributes
    sms = int(attrs["MultiProcessorCount"])
    regs = math.ceil(max(int(k.num_regs), 1) / 8) * 8 * threads
    by_regs = int(attrs["MaxRegistersPerMultiprocessor"]) // regs
    by_threads = int(attrs["MaxThreadsPerMultiProcessor"]) // threads
    smem = int(k.shared_size_bytes) + 1024  # the driver reserves 1 KB per block
    by_smem = int(attrs["MaxSharedMemoryPerMultiprocessor"]) // smem
    return max(1, sms * min(by_regs, by_threads, by_smem))


class Pinned:
    """A page-locked host buffer and the copies between it and device arrays."""

    def __init__(self, count: int, dtype: type = np.int32) -> None:
        self.dtype = np.dtype(dtype)
        self.count = 0
        self._mem = None
        self.array = np.empty(0, dtype=self.dtype)
        self.reserve(count)

    def reserve(self, count: int) -> bool:
        """Room for ``count`` items; True if the buffer moved (its contents are not kept)."""
        if count <= self.count:
            return False
        count = max(count, 2 * self.count)
        self._mem = cp.cuda.alloc_pinned_memory(count * self.dtype.itemsize)
        self.array = np.frombuffer(self._mem, dtype=self.dtype, count=count)
        self.count = count
        return True

    def to_device(self, dst: cp.ndarray, count: int, offset: int = 0) -> None:
        """Copy ``count`` items from item ``offset`` to ``dst`` at the same offset
        (asynchronous on the current stream)."""
        nbytes = count * self.dtype.itemsize
        if nbytes:
            stream = cp.cuda.get_current_stream().ptr
            start = offset * self.dtype.itemsize
            cp.cuda.runtime.memcpyAsync(
                dst.data.ptr + start, self.array.ctypes.data + start, nbytes,
                cp.cuda.runtime.memcpyHostToDevice, stream,
            )  # fmt: skip

    def from_device(self, src: cp.ndarray, count: int, offset: int = 0) -> None:
        """Copy ``count`` items of ``src`` (from item ``offset``) here, at the same offset."""
        nbytes = count * self.dtype.itemsize
        if nbytes:
            stream = cp.cuda.get_current_stream().ptr
            start = offset * self.dtype.itemsize
            cp.cuda.runtime.memcpyAsync(
                self.array.ctypes.data + start, src.data.ptr + start, nbytes,
                cp.cuda.runtime.memcpyDeviceToHost, stream,
            )  # fmt: skip


def synchronize() -> None:
    """Wait for the stream; an asynchronous CUDA fault surfaces here as a cupy error."""
    cp.cuda.get_current_stream().synchronize()


def encode_delta(
    cells: np.ndarray, values: np.ndarray, n_cells: int, out: np.ndarray | None = None
) -> np.ndarray:
    """``cell * 2 + blocked`` per changed cell, one entry per cell (the last value wins), into
    ``out[:n]`` when given (room for ``len(cells)`` codes). Sorted unique cells, as inflation
    gives them, take the short way: no copy but the codes themselves."""
    cells = np.asarray(cells)
    if cells.dtype != np.int64 or cells.ndim != 1:
        cells = cells.astype(np.int64).ravel()
    n = cells.size
    if n == 0:
        return np.empty(0, dtype=np.int32) if out is None else out[:0]
    values = np.asarray(values)
    if values.dtype != np.bool_ or values.shape != cells.shape:
        values = np.broadcast_to(values.astype(bool).ravel(), cells.shape)
    if n > 1 and not np.greater(cells[1:], cells[:-1]).all():
        rev_unique, rev_idx = np.unique(cells[::-1], return_index=True)
        cells, values = rev_unique, values[::-1][rev_idx]
        n = cells.size
    if cells[0] < 0 or cells[-1] >= n_cells:
        raise IndexError(f"a cell index is outside the map of {n_cells} cells")
    codes = np.empty(n, dtype=np.int32) if out is None else out[:n]
    np.left_shift(cells, 1, out=codes, casting="unsafe")
    np.bitwise_or(codes, values, out=codes)
    return codes
