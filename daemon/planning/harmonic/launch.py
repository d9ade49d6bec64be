"""How the CUDA engine (``cuda.py``) hands work to its stream: page-locked buffers, copies in
order with the launches, and a cooperative kernel launched straight through the driver, its
arguments kept in place.

CuPy's ``RawKernel.__call__`` converts every argument on each call, and for a cooperative
launch it also asks the driver for the kernel's occupancy and reads the device's attributes
before ``cuLaunchCooperativeKernel``. Here the parameter block (``void*[]`` of addresses of
typed values, what ``cuLaunchCooperativeKernel`` reads) is built once; a launch writes the few
values that change and makes the one driver call. H100, round 18: one launch's host time in a
tight loop 13–20 µs through CuPy, 7–10 µs so; in the 400² bench walk the median host time
inside ``relax_start`` went 0.120 → 0.061 ms (two calls on two machines). The grid is the
engine's own (``cuda._blocks``: never above the resident blocks, so the launch is as legal
as CuPy's).
"""

from __future__ import annotations

import ctypes
from collections.abc import Sequence

import cupy as cp
import numba
import numpy as np

H2D = cp.cuda.runtime.memcpyHostToDevice
D2H = cp.cuda.runtime.memcpyDeviceToHost
D2D = cp.cuda.runtime.memcpyDeviceToDevice


def pinned(count: int, dtype: type) -> np.ndarray:
    """``count`` values of ``dtype`` in page-locked host memory."""
    dtype = np.dtype(dtype)
    memory = cp.cuda.alloc_pinned_memory(max(1, count) * dtype.itemsize)
    return np.frombuffer(memory, dtype=dtype, count=count)


def copy_async(dst: int, src: int, nbytes: int, kind: int) -> None:
    """An asynchronous copy on the current stream, in order with its launches (pinned host
    memory: the host goes on at once)."""
    if nbytes:
        stream = cp.cuda.get_current_stream().ptr
        cp.cuda.runtime.memcpyAsync(dst, src, nbytes, kind, stream)


@numba.njit(cache=True, nogil=True)
def queue_changes(cells, code, fixed, fixed_host, queued, start) -> None:
    """``CudaField.set``'s cells queued for the next launch (``cell << 2 | code`` from
    ``start``) and their host fixedness written, in one pass: numpy's scatter and packing took
    0.55 ms of the 2000² walk's first sweep, 119 514 cells (dev VM; 0.27 so)."""
    for k in range(cells.size):
        c = cells[k]
        fixed_host[c] = fixed
        queued[start + k] = (c << 2) | code


_TYPES = {
    np.dtype(np.int32): ctypes.c_int32,
    np.dtype(np.uint32): ctypes.c_uint32,
    np.dtype(np.float32): ctypes.c_float,
    np.dtype(np.float64): ctypes.c_double,
}


_REALS = (ctypes.c_float, ctypes.c_double)


def _slot(value: object) -> ctypes._SimpleCData:
    """A typed cell for one kernel argument: a device array's address (None: a null
    pointer), or a numpy scalar."""
    if value is None:
        return ctypes.c_void_p()
    if isinstance(value, cp.ndarray):
        return ctypes.c_void_p(value.data.ptr)
    if isinstance(value, np.generic):
        return _TYPES[value.dtype](value.item())
    raise TypeError(f"a kernel argument must be a cupy array or a numpy scalar, not {value!r}")


class Launch:
    """``kernel`` (a ``cupy.RawKernel`` of a module compiled with cooperative groups) on
    ``blocks`` x ``threads``, with ``args`` as the kernel declares them: cupy arrays (their
    addresses are taken now: the arrays must outlive this and never be reallocated) and numpy
    scalars of the kernel's types. ``launch(**changed)`` writes the named arguments (by the
    position given in ``names``) and launches on the current stream."""

    def __init__(self, kernel: cp.RawKernel, blocks: int, threads: int,
                 args: Sequence[object], names: Sequence[str] = ()) -> None:  # fmt: skip
        self.func = int(kernel.kernel.ptr)
        self.blocks, self.threads = int(blocks), int(threads)
        self.slots = [_slot(a) for a in args]
        self.params = (ctypes.c_void_p * len(self.slots))(
            *(ctypes.addressof(s) for s in self.slots)
        )
        self.at = {name: k for k, name in enumerate(names) if name}

    def __call__(self, **changed: float) -> None:
        for name, value in changed.items():
            slot = self.slots[self.at[name]]
            slot.value = float(value) if isinstance(slot, _REALS) else int(value)
        cp.cuda.driver.launchCooperativeKernel(
            self.func, self.blocks, 1, 1, self.threads, 1, 1, 0,
            cp.cuda.get_current_stream().ptr, ctypes.addressof(self.params),
        )  # fmt: skip
