"""The harmonic field on the GPU: a thin CuPy wrapper round ``kernels/harmonic.cu`` and
``harmonic_reach.cu``, with ``cpu.CpuField``'s interface (``planner.py`` cannot tell them apart).

The kernel source is compiled once per process and float type (``functools.cache``; cupy
also keeps the binary in its on-disk cache), as the cuda planner's ``device.module`` does.
A relaxation is one cooperative launch — the map's changes ``set`` queued, every sweep, the
residual and pit checks, and the paper's Idx with the list of pits it leaves — with one copy
of the queued changes before it and, after it, one synchronisation for three copies into
page-locked host memory: Idx (one byte a cell, the host walks the descent itself), the sweep
count, residual, pit verdict and pit count, and the first pits. ``fill`` (a step's, launched
behind its sweeps by ``fill_start`` and gated on their pit count) finds the pits' basins from
Idx (pointer jumping) and fills them on the device (``harmonic_fill``: the fixed point
``fill.flood`` reaches by a heap, by passes over tiles of the basins, each iterated in shared
memory until stable, then Idx and the pits left, in one more launch); the host's flood, from
the few values of ``w`` it gathers, only takes what the passes left.
``float32`` by default: ``w`` grows about linearly with distance, so single precision holds
it at any grid size (``python -m sim.harmonic_bench plateau`` measures it); ``float64`` on
request.

Why so few host round trips (H100, 400² courtyard walk, each phase timed with a device
synchronisation round it): a step spent 0.39 ms in two ``set`` calls (cupy fancy-index
scatters of ``w`` and ``fixed``, each index array copied from pageable memory), 0.10 ms
clearing flags and reading Idx and the result in two blocking copies, and 0.33 ms in the
fill's gather and scatter (cupy indexing with int64 indices), against 0.48 ms of 40 sweeps.
"""

from __future__ import annotations

import functools
from collections.abc import Callable
from pathlib import Path

import cupy as cp
import numba
import numpy as np

from . import fill as fl
from . import relax as rx
from .launch import D2D, D2H, H2D, Launch, copy_async, pinned, queue_changes

SOURCES = tuple(
    Path(__file__).with_name("kernels") / name for name in ("harmonic.cu", "harmonic_reach.cu")
)
"""One module, compiled from these in order: the reach search uses the fill's tiling."""
THREADS = 256
FIRST_PITS = 64
"""Pits copied back with every relaxation's result (a step leaves a few: 2–27 measured);
``fill`` fetches the rest when there are more."""
FILL_PASSES = 2048
"""Passes the device's fill may take before the host's flood fills what they left. A pass
carries a value across a tile (``FILL_TILE``), so the passes a basin needs are about its
longest chain of tiles from where it spills; an uncapped launch could hold the step for as
long as the map is wide."""
FILL_TILE = 32
"""The fill's tile side (``harmonic.cu``'s ``FILL_TILE``): its tile marks are sized by it."""
_CODES = {(True, True): 0, (True, False): 1, (False, True): 2}
"""``set``'s (w is BLOCKED_W, fixed) → the kernel's change code (``harmonic.cu``): blocked or
cut off, newly reachable without a value yet, the goal's fixed zero."""
# Plain (not cooperative) launches for the fill's gather and scatter: every function of the
# cooperative module launches cooperatively, and cupy trims such a grid to the resident blocks.
_GATHER = cp.ElementwiseKernel("raw T w, int32 c", "T v", "v = w[c]", "harmonic_gather")
_SCATTER = cp.ElementwiseKernel("int32 c, T v", "raw T w", "w[c] = v", "harmonic_scatter")


@functools.cache
def _module(real: str) -> cp.RawModule:
    eps = "1.1920929e-7f" if real == "float" else "2.220446049250313e-16"
    return cp.RawModule(code="".join(p.read_text() for p in SOURCES),
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
        n = w0.size
        self.w = cp.asarray(w0.astype(self.dtype))
        self.fixed_host = fixed.astype(np.uint8)
        self.fixed = cp.asarray(self.fixed_host)
        self.prev = cp.empty_like(self.w) if self.jacobi else cp.empty(1, dtype=self.dtype)
        # The residual's two slots, the pit check's three and the pit count; zero before the
        # first launch, and each launch clears them as it ends.
        self.flags = cp.zeros(6, dtype=cp.uint32)
        self.worst, self.pits = self.flags[:2], self.flags[2:]
        # Result words; 4..7 a fill's launched behind a relaxation (``fill_start``).
        self.result = cp.zeros(8, dtype=cp.int32)
        self.result_host = pinned(8, np.int32)
        self.pit_list = cp.empty(n, dtype=cp.int32)
        self.pits_host = pinned(min(FIRST_PITS, n), np.int32)
        self.pit_count = 0
        # The changes ``set`` queued for the next launch (cell << 2 | code).
        self.changes = cp.empty(n, dtype=cp.int32)
        self.queued = pinned(n, np.int32)
        self.n_queued, self.late = 0, False
        # The fill's cells and values, on both sides.
        self.io_cells = cp.empty(n, dtype=cp.int32)
        self.io_vals = cp.empty(n, dtype=self.dtype)
        self.cells_host = pinned(n, np.int32)
        self.vals_host = pinned(n, self.dtype)
        self.vals = np.empty(n, dtype=self.dtype)  # the fill's host copy of some w
        self.mark = np.zeros(n, dtype=np.int8)
        self.cells = np.empty(n, dtype=np.int64)
        self.idx = cp.full(n, 4, dtype=cp.int8)
        self.idx_view = pinned(n, np.int8)
        self.buf = np.empty(n, dtype=np.int64)
        self.kernel = _module(self.real).get_function("harmonic_relax")
        self.blocks = _blocks(self.real, "harmonic_relax")
        self.fill_kernel = _module(self.real).get_function("harmonic_fill")
        self.fill_blocks = _blocks(self.real, "harmonic_fill")
        # The fill's three pass flags, its pit and basin counts; each launch clears them as it ends,
        # and leaves its map-sized lift (-1 off the basins) and its tiles' marks as it found
        # them.
        self.fill_flags = cp.zeros(5, dtype=cp.uint32)
        self.down = cp.empty(n, dtype=cp.int32)  # the fill's pointer jumping along Idx
        self.lift = cp.full(n, -1, dtype=self.dtype)
        tiles = -(-self.height // FILL_TILE) * -(-self.width // FILL_TILE)
        self.tile_active = cp.zeros(tiles, dtype=cp.uint8)
        self.tile_stamp = cp.full(tiles, -2, dtype=cp.int32)
        # The whole-map reach search's map, mask before the change, result and changed cells.
        # Its two masks (the map, the reach before the change) side by side, here and in
        # pinned memory: one DMA that runs while the host goes on, where two 4 MB ``set``s
        # from pageable memory held the host (the 2000² reveal's start took 1.9 ms with
        # them, H100 host). The event says when the pinned copy may be written again.
        self.masks_dev = cp.empty(2 * n, dtype=cp.uint8)
        self.masks_host = pinned(2 * n, np.uint8)
        self.masks_up = cp.cuda.Event(disable_timing=True)
        self.reach_dev = cp.empty(n, dtype=cp.uint8)
        self.changed_dev = cp.empty(n, dtype=cp.int32)
        self.reach_kernel = _module(self.real).get_function("harmonic_reach")
        self.reach_blocks = _blocks(self.real, "harmonic_reach")
        self.reach_passes = 0
        """The last whole-map reach search's device passes."""
        self.fill_passes = 0
        """The last step's device fill passes (0: no fill ran)."""
        self._launches()

    def _launches(self) -> None:
        """The three kernels' launches, their arguments in place (``launch.py`` says why);
        the named ones change from launch to launch."""
        h, w, n = np.int32(self.height), np.int32(self.width), self.w.size
        zero, real = np.int32(0), self.dtype.type
        self._relax_launch = Launch(self.kernel, self.blocks, THREADS,
            (self.w, self.fixed, self.prev, h, w, np.int32(self.jacobi), self.omega, zero,
             np.int32(self.check_every), np.float32(0), self.worst, self.result, self.idx, zero,
             self.pits, self.pit_list, self.changes, zero, zero),
            ("",) * 6 + ("omega", "sweeps", "", "tol") + ("",) * 3 + ("budget",) + ("",) * 3
            + ("n", "late"))  # fmt: skip
        # ``fill``'s, ungated (the host decided), and ``fill_start``'s: result words 4..7,
        # gated by the relaxation's pit count (word 3).
        self._fill_launch, self._fill_behind = (Launch(self.fill_kernel, self.fill_blocks,
            THREADS, (self.w, self.fixed, h, w, self.down, self.lift, real(fl.EPS),
                      np.int32(FILL_PASSES), self.fill_flags, self.result[at:], self.idx,
                      self.pit_list, self.tile_active, self.tile_stamp, gate),
            ("",) * 6 + ("eps",)) for at, gate in ((0, None), (4, self.result[3:4])))  # fmt: skip
        self._reach_launch = Launch(self.reach_kernel, self.reach_blocks, THREADS,
            (self.masks_dev[:n], self.masks_dev[n:], self.reach_dev, h, w, np.int32(self.goal),
             self.fill_flags, self.result, self.changed_dev, self.tile_stamp),
            ("",) * 5 + ("goal",))  # fmt: skip

    def set(self, cells: np.ndarray, w: float, fixed: bool) -> None:
        """Set ``cells``' ``w`` and fixedness, on the device at the next ``relax`` (``field``
        and ``fill`` apply them first too): blocked and freed cells before fixed zeros (the
        goal), whatever order the calls came in."""
        if cells.size == 0:
            return
        cells = np.ascontiguousarray(cells, dtype=np.int64)
        code = _CODES.get((w >= rx.BLOCKED_W, bool(fixed))) if w in (0.0, rx.BLOCKED_W) else None
        if code is None or self.n_queued + cells.size > self.queued.size:
            self._flush()
        if code is None or cells.size > self.queued.size:
            self.fixed_host[cells] = fixed
            dev = cp.asarray(cells)
            self.w[dev] = self.dtype.type(min(w, rx.BLOCKED_W))
            self.fixed[dev] = np.uint8(fixed)
            return
        queue_changes(cells, code, np.uint8(fixed), self.fixed_host, self.queued, self.n_queued)
        self.n_queued, self.late = self.n_queued + cells.size, self.late or code == 2

    def _flush(self) -> None:
        """Apply the queued changes without a relaxation (the kernel does, with no sweep)."""
        if self.n_queued:
            self.relax(0, 0.0, 0)

    def relax(self, sweeps: int, tol: float, budget: int | None = None) -> tuple[int, float, bool]:
        """As ``CpuField.relax``: sweeps, residual, and whether the field ends without a pit."""
        return self.relax_start(sweeps, tol, budget)()

    def keep_for_undo(self) -> None:
        """Room on the device for ``relax_start``'s copy of the field (after ``load``)."""
        self.w_kept, self.fixed_kept = cp.empty_like(self.w), cp.empty_like(self.fixed)

    def undo(self) -> None:
        """``w`` and the fixedness as the last ``relax_start(keep=True)``'s launch found them:
        copied back in the stream, after that launch. The launch's other outputs (Idx, the
        result words, the pit list) every launch writes afresh, and it clears its flags. The
        changes ``set`` before that launch are undone with it: a caller sets them again."""
        copy_async(self.w.data.ptr, self.w_kept.data.ptr, self.w.nbytes, D2D)
        copy_async(self.fixed.data.ptr, self.fixed_kept.data.ptr, self.fixed.nbytes, D2D)

    def relax_start(self, sweeps: int, tol: float, budget: int | None = None,
                    keep: bool = False) -> Callable[[], tuple[int, float, bool]]:  # fmt: skip
        """``relax`` launched: the function returned waits for it and gives its result. The
        host may meanwhile do anything but ``set`` (the queue's pinned buffer is the launch's
        until then). ``keep``: ``w`` and the fixedness copied first on the device (in the
        stream, before the launch), for ``undo``."""
        if keep:
            copy_async(self.w_kept.data.ptr, self.w.data.ptr, self.w.nbytes, D2D)
            copy_async(self.fixed_kept.data.ptr, self.fixed.data.ptr, self.fixed.nbytes, D2D)
        n = self.n_queued
        copy_async(self.changes.data.ptr, self.queued.ctypes.data, 4 * n, H2D)
        self._relax_launch(omega=self.omega, sweeps=sweeps, tol=tol, n=n, late=self.late,
                           budget=sweeps if budget is None else budget)  # fmt: skip
        self.n_queued, self.late = 0, False
        self.launches += 1
        return self._relaxed

    def _relaxed(self) -> tuple[int, float, bool]:
        self._fetch()
        done, bits, settled, self.pit_count = (int(v) for v in self.result_host[:4])
        return done, float(np.array([bits], dtype=np.int32).view(np.float32)[0]), bool(settled)

    def fill(self, eps: float = fl.EPS) -> tuple[int, int]:
        """Fill the basins of the pits the last relaxation left, on the device
        (``harmonic_fill``, one cooperative launch: the basins from Idx by pointer jumping,
        their ``w`` filled, Idx written and the pits left listed), the host flood
        (``fill.flood``) only for cells the device's passes did not reach within
        ``FILL_PASSES``. Returns the basins' cells and those left unfilled (0: no pit)."""
        self._flush()
        self.fill_passes = 0
        if self.pit_count == 0:
            return 0, 0
        self._fill_launch(eps=eps)
        self.launches += 1
        self._fetch()
        self.fill_passes, n_basin = int(self.result_host[0]), int(self.result_host[1])
        self.pit_count = int(self.result_host[3])
        if self.pit_count == 0:
            return n_basin, 0
        more, left = self._fill_host(eps)
        return n_basin + more, left

    def fill_start(self, eps: float = fl.EPS) -> Callable[[], tuple[int, int]]:
        """``fill`` launched right behind the relaxation just launched, before the host knows
        whether it leaves a pit; the function returned gives ``fill``'s answer after that
        relaxation's wait (no second round trip between the sweeps and the fill). The launch
        is gated on the device by the relaxation's own pit count (result word 3,
        ``harmonic_fill``'s ``gate``): with none it returns at once and writes nothing, and the
        answer is ``fill``'s without a launch, (0, 0) with ``fill_passes`` 0.

        Invariant: the field, Idx, pit list, ``fill_passes`` and counts are those of ``fill``
        called after the relaxation's wait. Both decide on the same word (the host's
        ``pit_count`` is word 3 as fetched), whether the relaxation settled, met ``tol`` or
        neither (a step fills in every case), and both fill the field that relaxation left:
        nothing may be ``set`` between ``relax_start`` and this (``fill``'s ``_flush`` then has
        nothing to apply). The fill's words are 4..7, read only when word 3 is not zero; Idx
        and the pits come back in the relaxation's wait, which follows both launches, so the
        host's flood (``_fill_host``, for what ``FILL_PASSES`` left) reads the fill's. ``undo``
        after the wait restores ``w`` and the fixedness past both launches (stream order); the
        fill leaves its scratch (lift, tile marks) as it found them, a gated one never touches
        it. Plain ``relax`` (``plan``'s, its omega-1 rest, ``converge``, a path read's retry,
        ``_flush``) launches no fill, so a gate never reads another launch's count."""
        self._fill_behind(eps=eps)
        self.launches += 1
        return lambda: self._filled_behind(eps)

    def _filled_behind(self, eps: float) -> tuple[int, int]:
        if self.pit_count == 0:  # the relaxation's: no pit, so the gate kept the fill out
            self.fill_passes = 0
            return 0, 0
        self.fill_passes, n_basin = int(self.result_host[4]), int(self.result_host[5])
        self.pit_count = int(self.result_host[7])
        if self.pit_count == 0:
            return n_basin, 0
        more, left = self._fill_host(eps)
        return n_basin + more, left

    def reach_search(self, blocked: np.ndarray, before: np.ndarray, goal: int) -> np.ndarray:
        """``Reach``'s whole-map search on the device (``harmonic_reach``): the padded flat
        cells (int64, in no set order) whose reach by the goal in ``blocked`` differs from
        ``before`` (both bool, the host's). One launch, the two masks up and the changed
        cells back: the host's breadth-first search over the map took 1.4 ms of a 400² step
        and 55 ms of a 2000² one (H100 host, the bench walk)."""
        return self.reach_search_start(blocked, before, goal)()

    def reach_search_start(self, blocked: np.ndarray, before: np.ndarray,
                           goal: int) -> Callable[[], np.ndarray]:  # fmt: skip
        """``reach_search`` started: the masks are copied up (the host may change them once
        this returns) and the search launched; the function returned waits for its answer.
        ``Reach`` runs its cut-off try on the host meanwhile. A search never waited for is
        harmless: the next launch on the stream follows it."""
        n = blocked.size
        self.masks_up.synchronize()  # the last search's copy has left the pinned masks
        np.copyto(self.masks_host[:n], blocked.view(np.uint8))
        np.copyto(self.masks_host[n:], before.view(np.uint8))
        copy_async(self.masks_dev.data.ptr, self.masks_host.ctypes.data, 2 * n, H2D)
        self.masks_up.record()
        self._reach_launch(goal=goal)
        self.launches += 1
        return self._reach_changed

    def _reach_changed(self) -> np.ndarray:
        copy_async(self.result_host.ctypes.data, self.result.data.ptr, 16, D2H)
        cp.cuda.get_current_stream().synchronize()
        self.reach_passes = int(self.result_host[0])
        # In the device's order, not sorted: ``Reach`` and ``set`` take the cells in any
        # order, and sorting ~140 k of them took ~1.2 ms (dev VM, numpy 2.4).
        return self.changed_dev[: int(self.result_host[3])].get().astype(np.int64)

    def _pits(self) -> np.ndarray:
        """The pits the last launch listed (int32; read before the next launch's fetch)."""
        if self.pit_count <= self.pits_host.size:
            return self.pits_host[: self.pit_count]
        return self.pit_list[: self.pit_count].get()

    def _fetch(self) -> None:
        """Idx, the result words and the first pits into pinned memory, then synchronise."""
        copy_async(self.idx_view.ctypes.data, self.idx.data.ptr, self.idx_view.size, D2H)
        copy_async(self.result_host.ctypes.data, self.result.data.ptr, 32, D2H)
        copy_async(self.pits_host.ctypes.data, self.pit_list.data.ptr, 4 * self.pits_host.size, D2H)
        # The copies wait for the launch; the queued changes' buffer is free again after.
        cp.cuda.get_current_stream().synchronize()

    def _fill_host(self, eps: float) -> tuple[int, int]:
        """``fill.py``'s flood on the host, for the pits the device's passes left: the cells
        up, their ``w`` down, the flood, the basins' ``w`` up again."""
        counts = fl.basins(self.idx_view, self.fixed_host, self.width, self._pits(),
                           self.mark, self.cells)  # fmt: skip
        n_basin, total = counts[0], sum(counts)
        cells = self.cells[:total]
        # Gather: the cells up (int32, pinned), their w down, one synchronisation.
        self.cells_host[:total] = cells
        copy_async(self.io_cells.data.ptr, self.cells_host.ctypes.data, 4 * total, H2D)
        _GATHER(self.w, self.io_cells[:total], self.io_vals[:total])
        copy_async(self.vals_host.ctypes.data, self.io_vals.data.ptr,
                   total * self.dtype.itemsize, D2H)  # fmt: skip
        cp.cuda.get_current_stream().synchronize()
        self.vals[cells] = self.vals_host[:total]
        left = fl.flood(self.vals, self.width, self.cells, *counts, eps, self.mark,
                        self.idx_view)  # fmt: skip
        # Scatter: the basins' new w up, to the cells already on the device (the basins come
        # first); the next launch or copy on the stream waits for it. The pinned values are
        # not written again before a synchronisation (the next relax).
        self.vals_host[:n_basin] = self.vals[cells[:n_basin]]
        copy_async(self.io_vals.data.ptr, self.vals_host.ctypes.data,
                   n_basin * self.dtype.itemsize, H2D)  # fmt: skip
        _SCATTER(self.io_cells[:n_basin], self.io_vals[:n_basin], self.w)
        self.pit_count = left
        return n_basin, left

    def descend(self, start: int) -> np.ndarray | None:
        k = _walk(self.idx_view, self.width, start, self.goal, self.buf)
        return None if k < 0 else self.buf[:k].copy()

    def field(self) -> np.ndarray:
        self._flush()
        return self.w.get().astype(np.float64)
