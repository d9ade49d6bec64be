"""The harmonic field on the GPU: a thin CuPy wrapper round ``kernels/harmonic.cu``, with
``cpu.CpuField``'s interface (``planner.py`` cannot tell them apart).

The kernel source is compiled once per process and float type (``functools.cache``; cupy
also keeps the binary in its on-disk cache), as the cuda planner's ``device.module`` does.
A relaxation is one cooperative launch — every sweep, the residual and pit checks, and the
paper's Idx with the list of pits it leaves — then one copy of Idx (one byte a cell) into
page-locked host memory and one of the sweep count, residual, pit verdict and pit count: the
host walks the descent itself. ``fill`` (after a replanning step's sweeps, when pits are
left) fills their basins on the host (``fill.py``) from the pits, Idx and the few values of
``w`` it reads, and writes back the basins' ``w``. ``float32`` by
default: ``w`` grows about linearly with distance, so single precision holds it at any grid
size (``python -m sim.harmonic_bench plateau`` measures it); ``float64`` on request.
"""

from __future__ import annotations

import functools
from pathlib import Path

import cupy as cp
import numba
import numpy as np

from . import fill as fl
from . import relax as rx

SOURCE = Path(__file__).with_name("kernels") / "harmonic.cu"
THREADS = 256


@functools.cache
def _module(real: str) -> cp.RawModule:
    eps = "1.1920929e-7f" if real == "float" else "2.220446049250313e-16"
    return cp.RawModule(code=SOURCE.read_text(),
                        options=("--std=c++17", f"-DREAL={real}", f"-DREAL_EPS={eps}")
                        + (("--use_fast_math",) if real == "float" else ()),
                        enable_cooperative_groups=True)  # fmt: skip


@functools.cache
def _blocks(real: str, function: str) -> int:
    """Blocks of ``function`` resident at once: a cooperative launch may not have more."""
    from ..cuda.device import resident_blocks

    k = _module(real).get_function(function)
    sms = int(cp.cuda.Device().attributes["MultiProcessorCount"])
    # Four blocks of 256 a multiprocessor is enough to cover the grid's memory latency; the
    # occupancy bound keeps the cooperative launch legal if the kernel ever needs more.
    return max(1, min(resident_blocks(k, THREADS), 4 * sms))


@numba.njit(cache=True, nogil=True)
def _walk(idx: np.ndarray, width: int, start: int, goal: int, out: np.ndarray) -> int:
    """Follow Idx from ``start``; the count of cells to the goal, -1 if it stops short."""
    cur, k = start, 0
    while k < out.size:
        out[k] = cur
        k += 1
        if cur == goal:
            return k
        d = idx[cur]
        if d == 4:
            return -1
        cur = cur + (d // 3 - 1) * width + d % 3 - 1
    return -1


class CudaField:
    backend = "cuda"

    def __init__(self, order: str = "rb", omega: float = 1.3, check_every: int = 5,
                 dtype: type = np.float32) -> None:  # fmt: skip
        if order not in ("rb", "jacobi"):
            raise ValueError(f"the GPU sweeps rb or jacobi, not {order!r}")
        self.jacobi = order == "jacobi"
        self.dtype = np.dtype(dtype)
        self.real = "double" if self.dtype == np.float64 else "float"
        self.omega = self.dtype.type(omega if order == "rb" else 1.0)
        self.check_every = int(check_every)
        self.width = self.height = self.goal = 0
        self.launches = 0

    def load(self, fixed: np.ndarray, w0: np.ndarray, width: int, goal: int) -> None:
        self.width, self.goal = int(width), int(goal)
        self.height = fixed.size // self.width
        self.w = cp.asarray(w0.astype(self.dtype))
        self.fixed_host = fixed.astype(np.uint8)
        self.fixed = cp.asarray(self.fixed_host)
        self.prev = cp.empty_like(self.w) if self.jacobi else cp.empty(1, dtype=self.dtype)
        # The residual's two slots, the pit check's three and the pit count, cleared by one
        # launch a relax.
        self.flags = cp.zeros(6, dtype=cp.uint32)
        self.worst, self.pits = self.flags[:2], self.flags[2:]
        self.result = cp.zeros(4, dtype=cp.int32)
        self.pit_list = cp.empty(w0.size, dtype=cp.int32)
        self.pit_count = 0
        self.vals = np.empty(w0.size, dtype=self.dtype)  # the fill's host copy of some w
        self.mark = np.zeros(w0.size, dtype=np.int8)
        self.cells = np.empty(w0.size, dtype=np.int64)
        self.idx = cp.full(w0.size, 4, dtype=cp.int8)
        self.idx_host = cp.cuda.alloc_pinned_memory(w0.size)
        self.idx_view = np.frombuffer(self.idx_host, dtype=np.int8, count=w0.size)
        self.buf = np.empty(w0.size, dtype=np.int64)
        self.kernel = _module(self.real).get_function("harmonic_relax")
        self.blocks = _blocks(self.real, "harmonic_relax")

    def set(self, cells: np.ndarray, w: float, fixed: bool) -> None:
        if cells.size == 0:
            return
        # Plain cupy scatters: every function of the cooperative module launches
        # cooperatively, and cupy trims such a grid to the resident blocks.
        dev = cp.asarray(np.ascontiguousarray(cells, dtype=np.int64))
        self.w[dev] = self.dtype.type(min(w, rx.BLOCKED_W))
        self.fixed[dev] = np.uint8(fixed)
        self.fixed_host[cells] = fixed

    def relax(self, sweeps: int, tol: float, budget: int | None = None) -> tuple[int, float, bool]:
        """As ``CpuField.relax``: sweeps, residual, and whether the field ends without a pit."""
        self.flags.fill(0)
        self.kernel(
            (self.blocks,), (THREADS,),
            (self.w, self.fixed, self.prev, np.int32(self.height), np.int32(self.width),
             np.int32(self.jacobi), self.omega, np.int32(sweeps), np.int32(self.check_every),
             np.float32(tol), self.worst, self.result, self.idx,
             np.int32(sweeps if budget is None else budget), self.pits, self.pit_list),
        )  # fmt: skip
        return self._read()

    def _read(self) -> tuple[int, float, bool]:
        self.launches += 1
        self.idx.get(out=self.idx_view)
        done, bits, settled, self.pit_count = (int(v) for v in self.result.get())
        return done, float(np.array([bits], dtype=np.int32).view(np.float32)[0]), bool(settled)

    def fill(self, eps: float = fl.EPS) -> tuple[int, int]:
        """Fill the basins of the pits the last relaxation left (``fill.py``): their ``w`` on
        the device, their Idx on the host. Returns the basins' cells and those the flood did
        not reach (0: the field has no pit)."""
        if self.pit_count == 0:
            return 0, 0
        pits = self.pit_list[: self.pit_count].get().astype(np.int64)
        counts = fl.basins(self.idx_view, self.fixed_host, self.width, pits, self.mark,
                           self.cells)  # fmt: skip
        n_basin = counts[0]
        cells = self.cells[: sum(counts)]
        dev = cp.asarray(cells)
        self.vals[cells] = self.w[dev].get()
        left = fl.flood(self.vals, self.width, self.cells, *counts, eps, self.mark,
                        self.idx_view)  # fmt: skip
        self.w[dev[:n_basin]] = cp.asarray(self.vals[cells[:n_basin]])
        self.pit_count = left
        return n_basin, left

    def descend(self, start: int) -> np.ndarray | None:
        k = _walk(self.idx_view, self.width, start, self.goal, self.buf)
        return None if k < 0 else self.buf[:k].copy()

    def field(self) -> np.ndarray:
        return self.w.get().astype(np.float64)
