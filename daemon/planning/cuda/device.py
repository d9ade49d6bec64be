"""The CUDA side of the cuda backend: sources, compilation, launches and host transfers.

CUDA C lives in ``kernels/*.cu`` (and ``*.cuh``) and is compiled once per process (cupy also
keeps the binaries in its on-disk cache). Everything here is thin: it sizes
launches, moves bytes through pinned host buffers (a transfer is one asynchronous copy on the
stream, with no pageable staging, or none at all where a kernel writes into a mapped buffer
itself) and leaves the algorithms to the kernels.
"""

from __future__ import annotations

import functools
import math
import threading
from pathlib import Path

import cupy as cp
import numpy as np

from . import abi

KERNELS = Path(__file__).with_name("kernels")
SPIN_S = 1e-3
"""How long a wait for a call polls before it lets other threads have the GIL between polls: a
step at 400² takes 0.05-0.3 ms, and a poll sees the done word within a microsecond, where a
wake-up from a sleep costs tens. Longer calls (a plan from scratch at 2000² and up) then let
the daemon's event loop run while they wait."""

DEVICE_LOCK = threading.Lock()
"""One planning call on the device at a time: the resident loop's grid barrier needs every one
of its blocks resident, which a second concurrent launch could prevent."""


DEFINES: tuple[str, ...] = ()
"""Macros every kernel is compiled with: none in the product. The link profile
(``scripts/profile_cuda_links.py``) sets ``("GB_PROFILE",)`` before the first compile
(``kernels/profile.cuh``)."""


@functools.cache
def module(name: str) -> cp.RawModule:
    """``kernels/<name>.cu`` compiled (cached for the process)."""
    code = (KERNELS / f"{name}.cu").read_text()
    # NVRTC compiles a string: name the folder so `#include "tile_scans.cuh"` resolves.
    defines = tuple(f"-D{d}" for d in DEFINES)
    return cp.RawModule(code=code, options=("--std=c++17", f"-I{KERNELS}", *defines))


@functools.cache
def kernel(name: str, function: str) -> cp.RawKernel:
    return module(name).get_function(function)


def resident_blocks(k: cp.RawKernel, threads: int = abi.THREADS) -> int:
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
    """A page-locked host buffer and the copies between it and device arrays. ``mapped``: also
    mapped into the device's address space (``device_ptr``), for kernels that read and write
    it directly (zero-copy), at PCIe latency per access."""

    def __init__(self, count: int, dtype: type = np.int32, *, mapped: bool = False) -> None:
        self.dtype = np.dtype(dtype)
        self.mapped = mapped
        self.count = 0
        self.device_ptr = 0
        self._mem = None
        self.array = np.empty(0, dtype=self.dtype)
        self.view = memoryview(self.array)
        self.reserve(count)

    def reserve(self, count: int) -> bool:
        """Room for ``count`` items, zeroed when it moves; True if the buffer moved (the old
        contents are not kept, and ``device_ptr`` changes)."""
        if count <= self.count:
            return False
        count = max(count, 2 * self.count)
        flags = cp.cuda.runtime.hostAllocMapped if self.mapped else 0
        mem = cp.cuda.PinnedMemory(count * self.dtype.itemsize, flags)
        self._mem = cp.cuda.PinnedMemoryPointer(mem, 0)
        self.array = np.frombuffer(self._mem, dtype=self.dtype, count=count)
        self.array[:] = 0
        # Python-level reads and stores of single words and struct packs go through this: a
        # memoryview's item or buffer costs less than numpy's (~1 µs less, cold, per access).
        self.view = memoryview(self.array)
        if self.mapped:
            self.device_ptr = int(cp.cuda.runtime.pointerGetAttributes(mem.ptr).devicePointer)
        self.count = count
        return True

    @property
    def memory(self) -> object:
        """The allocation itself: holding it keeps the buffer alive after ``reserve`` moves."""
        return self._mem

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
        cells, values = unique_last(cells, values)
        n = cells.size
    if cells[0] < 0 or cells[-1] >= n_cells:
        raise IndexError(f"a cell index is outside the map of {n_cells} cells")
    codes = np.empty(n, dtype=np.int32) if out is None else out[:n]
    np.left_shift(cells, 1, out=codes, casting="unsafe")
    np.bitwise_or(codes, values, out=codes)
    return codes


def unique_last(cells: np.ndarray, values: np.ndarray | bool) -> tuple[np.ndarray, np.ndarray]:
    """Sorted unique ``cells`` (int64) and, for each, the value it was given last."""
    cells = np.asarray(cells, dtype=np.int64).ravel()
    values = np.broadcast_to(np.asarray(values, dtype=bool).ravel(), cells.shape)
    rev_unique, rev_idx = np.unique(cells[::-1], return_index=True)
    return rev_unique, values[::-1][rev_idx]
