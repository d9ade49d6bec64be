"""The cuda backend: EDS and DSS in CuPy raw kernels, bit-exact with the CPU backends.

Two variants (``kernels/``):

- ``fast`` (default, ``fast.cu``): one persistent launch per planning call. 32 x 32 tiles
  settle in shared memory before a grid-wide exchange; only flagged tiles are processed, so
  an EDS update works around the change. Per call: the delta up (one copy), one launch,
  the statistics down (one copy and the only synchronisation).
- ``paper`` (``paper.cu``): Díaz-Toro et al.'s Figure 4 form, for comparison: read-only and
  write-only maps for g, pred and incon, one ``kernel_planner`` launch per iteration and
  ``flag_stop`` read back after each.

EDS semantics are the CPU's: newly blocked cells are raised to INF, and so is every cell
all of whose supporting neighbours (g[n] + cost == g[v]) are raised — exactly the cells whose
cost must rise (``fast``; ``paper`` raises the whole subtree of its stored pred map, a
superset); then raised and newly freed cells are re-seeded from their neighbours and
everything is relaxed until nothing changes. Every value is an integer path cost, so the
fixpoint is the exact field, equal to the CPU's cell for cell whatever the order of relaxation.

``path`` runs on the device with the rule of ``interface.reference_path`` (``path_tiles.cu``:
tile-to-tile jumps, segments walked in parallel; ``path.cu``: one warp walks every cell); only
the path's cells come back. Test hook: ``inject_fault(exc)`` makes the next public call raise
``exc`` before touching the device, to test the CPU fallback with a real cupy error.
"""

from __future__ import annotations

import time

import cupy as cp
import numpy as np

from . import cuda_kernels as ck
from .grid import INF, Cell, in_bounds
from .interface import Planner, UpdateStats, checked_plan_input

VARIANTS = ("fast", "paper")
PATH_MODES = ("tiles", "walk")
"""``tiles``: path_tiles.cu, tile-to-tile jumps with the segments walked in parallel (default);
``walk``: path.cu, one warp walks every cell in a shared-memory window."""
PAPER_THREADS = 256


class CudaPlanner(Planner):
    """EDS/DSS on one CUDA device; ``variant`` is ``fast`` or ``paper``.

    ``fast`` options (BENCHMARKS.md, "Planning on the GPU", compares them): ``scans`` the
    in-tile relaxation (0 Jacobi sweeps, 1 + row/column scans, 2 + diagonal scans: the
    default, fastest for large DSS), ``min_blocks`` blocks per SM the kernel is compiled for
    (1: 64 registers, no spills), ``path_mode`` (``PATH_MODES``). Calls are serialised on
    the device (``cuda_kernels.DEVICE_LOCK``): the persistent kernel needs every block resident.
    """

    def __init__(
        self,
        variant: str = "fast",
        *,
        scans: int = 2,
        min_blocks: int = 1,
        path_mode: str = "tiles",
        max_blocks: int | None = None,
    ) -> None:
        if variant not in VARIANTS:
            raise ValueError(f"unknown variant {variant!r}; choose one of {VARIANTS}")
        if path_mode not in PATH_MODES:
            raise ValueError(f"unknown path_mode {path_mode!r}; choose one of {PATH_MODES}")
        self.path_mode = path_mode
        self.max_blocks = max_blocks  # caps the persistent grid (experiments; None: all resident)
        self.variant = variant
        self.name = f"cuda-{variant}"
        self._shape: tuple[int, int] = (0, 0)
        self._goal: Cell = (0, 0)
        self._fault: BaseException | None = None
        self.last_stats: UpdateStats | None = None
        self._defines = (f"SCANS={int(scans)}", f"MIN_BLOCKS={int(min_blocks)}")
        # The host mirror of ``_io``: fast.cu's ctrl words, then the path (see _allocate).
        self._io_host = ck.Pinned(ck.IO_PATH + 2 + 1024, np.int32)
        self._delta_host = ck.Pinned(1024, np.int32)
        self._delta = cp.zeros(1024, dtype=np.int32)
        self._path_guess = 256
        self._slot = 0  # paper: which flag_stop slot the next launch writes
        # fast, last call: in-tile sweeps summed over tiles, cells raised to INF, tiles run.
        self.sweeps = self.raised_cells = self.tiles = 0

    # -- test hook ----------------------------------------------------------------------------

    def inject_fault(self, exc: BaseException) -> None:
        """Make the next public call raise ``exc`` (tests of the CPU fallback)."""
        self._fault = exc

    def _check_fault(self) -> None:
        if self._fault is not None:
            exc, self._fault = self._fault, None
            raise exc

    # -- state ----------------------------------------------------------------------------------

    def _allocate(self, shape: tuple[int, int]) -> None:
        h, w = shape
        n = h * w
        self._shape = shape
        self._blocked_d = cp.zeros(n, dtype=np.uint8)
        self._g = cp.full(n, INF, dtype=np.int32)
        self._path_cap = int(min(n, 4 * (h + w) + 1024))
        # One device buffer holds fast.cu's ctrl words (barrier count, statistics) and then the
        # path, so a replanning step reads both back with one copy and one synchronisation.
        self._io = cp.zeros(ck.IO_PATH + 2 + self._path_cap, dtype=np.int32)
        self._ctrl = self._io[: ck.IO_PATH].view(np.uint32)
        self._path_d = self._io[ck.IO_PATH :]
        self._io_host.reserve(ck.IO_PATH + 2 + self._path_cap)
        self._io_host.array[: ck.IO_PATH] = 0  # a fresh barrier count
        tiles = -(-h // ck.TILE) * -(-w // ck.TILE)
        self._tiles = tiles
        if self.path_mode == "tiles":
            self._exits = cp.zeros(2 * 124 * tiles, dtype=np.int32)
            self._segs = cp.zeros(4 * self._path_cap, dtype=np.int32)
            self._path_ctrl = cp.zeros(64, dtype=np.uint32)
            self._path_bar = 0  # its barrier count: 2 barriers x blocks per launch
            k = ck.kernel("path_tiles", "path_tiles")
            sms = int(cp.cuda.Device().attributes["MultiProcessorCount"])
            self._path_blocks = int(min(tiles, ck.resident_blocks(k, 128), 8 * sms))
        if self.variant == "fast":
            self._raised = cp.zeros(n, dtype=np.uint8)
            self._flags = cp.zeros(3 * tiles, dtype=np.uint32)
            k = self._k_fast()
            self._blocks = int(min(tiles, ck.resident_blocks(k), self.max_blocks or tiles))
        else:
            self._g_w = cp.full(n, INF, dtype=np.int32)
            self._pred = cp.full(n, -1, dtype=np.int8)
            self._pred_w = cp.full(n, -1, dtype=np.int8)
            self._incon = cp.zeros(n, dtype=np.uint8)
            self._incon_w = cp.zeros(n, dtype=np.uint8)
            self._raised = cp.zeros(n, dtype=np.uint8)
            self._raised_w = cp.zeros(n, dtype=np.uint8)
            # flag_stop of the two slots, then a 64-bit count of the cells relaxed so far
            self._flag = cp.zeros(4, dtype=np.int32)
            self._flag_host = ck.Pinned(4, np.int32)
            self._flag_host.array[:] = 0

    def _k_fast(self) -> cp.RawKernel:
        return ck.kernel("fast", "plan_persistent", self._defines)

    def _upload_delta(self, cells: np.ndarray, blocked: np.ndarray) -> int:
        h, w = self._shape
        codes = ck.encode_delta(cells, blocked, h * w)
        n = int(codes.size)
        if n > self._delta.size:
            self._delta = cp.zeros(max(n, 2 * self._delta.size), dtype=np.int32)
        self._delta_host.reserve(n)
        self._delta_host.array[:n] = codes
        self._delta_host.to_device(self._delta, n)
        return n

    def _require_plan(self) -> None:
        if self._shape == (0, 0):
            raise RuntimeError("call plan(blocked, goal) before update/replan")

    # -- planning -------------------------------------------------------------------------------

    def plan(self, blocked: np.ndarray, goal: Cell) -> UpdateStats:
        t0 = time.perf_counter()
        self._check_fault()
        blocked, shape, goal = checked_plan_input(blocked, goal)
        with ck.DEVICE_LOCK:
            if shape != self._shape:
                self._allocate(shape)
            self._goal = goal
            self._blocked_d.set(np.ascontiguousarray(blocked, dtype=np.uint8).ravel())
            return self._run(eds=False, n_delta=0, t0=t0)

    def update(self, cells: np.ndarray, blocked: np.ndarray) -> UpdateStats:
        return self._change(cells, blocked, eds=True)

    def replan(self, cells: np.ndarray, blocked: np.ndarray) -> UpdateStats:
        return self._change(cells, blocked, eds=False)

    def _change(self, cells: np.ndarray, blocked: np.ndarray, eds: bool) -> UpdateStats:
        t0 = time.perf_counter()
        self._check_fault()
        self._require_plan()
        with ck.DEVICE_LOCK:
            n = self._upload_delta(cells, blocked)
            return self._run(eds=eds, n_delta=n, t0=t0)

    def _run(self, eds: bool, n_delta: int, t0: float) -> UpdateStats:
        if self.variant == "fast":
            iterations, touched = self._run_fast(eds, n_delta)
        else:
            iterations, touched = self._run_paper(eds, n_delta)
        stats = UpdateStats(iterations, touched, (time.perf_counter() - t0) * 1e3)
        self.last_stats = stats
        return stats

    def update_and_path(
        self, cells: np.ndarray, blocked: np.ndarray, start: Cell, *, full: bool = False
    ) -> tuple[UpdateStats, np.ndarray]:
        """The repair launch, the path launch and one copy back of statistics and path, queued
        back to back with a single synchronisation (``fast``; ``paper`` syncs per iteration
        anyway and takes the interface's default)."""
        if self.variant != "fast":
            stats, path = super().update_and_path(cells, blocked, start, full=full)
            self.last_stats = stats  # the whole step's, as for fast
            return stats, path
        t0 = time.perf_counter()
        self._check_fault()
        self._require_plan()
        start = (int(start[0]), int(start[1]))
        with ck.DEVICE_LOCK:
            n = self._upload_delta(cells, blocked)
            self._launch_fast(eds=not full, n_delta=n)
            if in_bounds(self._shape, start):
                path = self._path_locked(start, with_ctrl=True)
            else:
                self._io_host.from_device(self._io, ck.CTRL_READ)
                ck.synchronize()
                path = np.empty((0, 2), dtype=np.int32)
            iterations, touched = self._read_fast_stats()
        stats = UpdateStats(iterations, touched, (time.perf_counter() - t0) * 1e3)
        self.last_stats = stats
        return stats, path

    def _ctrl_host(self) -> np.ndarray:
        """The host copy of the ctrl words read back after the last fast launch."""
        return self._io_host.array[: ck.CTRL_READ].view(np.uint32)

    def _run_fast(self, eds: bool, n_delta: int) -> tuple[int, int]:
        self._launch_fast(eds, n_delta)
        self._io_host.from_device(self._io, ck.CTRL_READ)
        ck.synchronize()
        return self._read_fast_stats()

    def _read_fast_stats(self) -> tuple[int, int]:
        st = self._ctrl_host()
        self.sweeps, self.raised_cells = int(st[ck.C_SWEEPS]), int(st[ck.C_RAISED])
        self.tiles = int(st[ck.C_TILES])
        return int(st[ck.C_ROUNDS]), self.raised_cells + int(st[ck.C_CHANGED])

    def _launch_fast(self, eds: bool, n_delta: int) -> None:
        h, w = self._shape
        goal = self._goal[0] * w + self._goal[1]
        st = self._ctrl_host()  # C_BAR: the barrier count the previous launch ended with
        self._k_fast()(
            (self._blocks,), (ck.THREADS,),
            (self._g, self._blocked_d, self._raised, self._delta, np.int32(n_delta), self._flags,
             self._ctrl, np.int32(h), np.int32(w), np.int32(goal), np.int32(1 if eds else 0),
             np.uint32(st[ck.C_BAR])),
        )  # fmt: skip

    # -- the paper's form ----------------------------------------------------------------------

    def _launch_paper(self, name: str, args: tuple, n: int) -> None:
        k = ck.kernel("paper", name)
        k((-(-n // PAPER_THREADS),), (PAPER_THREADS,), args)

    def _flag_after(self, name: str, args: tuple) -> bool:
        """Launch one iteration and read its flag_stop back (the paper's per-iteration sync)."""
        h, w = self._shape
        self._launch_paper(name, (*args, self._flag, np.int32(self._slot)), h * w)
        self._flag_host.from_device(self._flag, 4)
        ck.synchronize()
        changed = bool(self._flag_host.array[self._slot])
        self._slot ^= 1
        return changed

    def _run_paper(self, eds: bool, n_delta: int) -> tuple[int, int]:
        h, w = self._shape
        n = h * w
        goal = np.int32(self._goal[0] * w + self._goal[1])
        hw = (np.int32(h), np.int32(w))
        if n_delta:
            self._launch_paper(
                "paper_apply",
                (self._delta, np.int32(n_delta), self._blocked_d, self._raised, self._raised_w,
                 self._incon, np.int32(1 if eds else 0)),
                n_delta,
            )  # fmt: skip
        relaxed_before = int(self._flag_host.array[2:4].view(np.uint64)[0])
        iterations = 0
        if not eds:
            self._launch_paper(
                "paper_init",
                (self._g, self._pred, self._incon, self._incon_w, self._raised, self._raised_w,
                 self._blocked_d, *hw, goal, self._flag),
                n,
            )  # fmt: skip
            self._slot = 0
        else:
            while True:  # raise the pred-tree descendants of newly blocked cells
                iterations += 1
                changed = self._flag_after(
                    "kernel_raise", (self._pred, self._raised, self._raised_w, *hw)
                )
                self._raised, self._raised_w = self._raised_w, self._raised
                if not changed:
                    break
            self._launch_paper(
                "paper_reset",
                (self._g, self._pred, self._raised, self._raised_w, self._incon, self._blocked_d,
                 np.int32(n)),
                n,
            )  # fmt: skip
        while True:
            iterations += 1
            changed = self._flag_after(
                "kernel_planner",
                (self._g, self._g_w, self._pred, self._pred_w, self._incon, self._incon_w,
                 self._blocked_d, *hw, goal),
            )  # fmt: skip
            self._g, self._g_w = self._g_w, self._g
            self._pred, self._pred_w = self._pred_w, self._pred
            self._incon, self._incon_w = self._incon_w, self._incon
            if not changed:
                break
        relaxed = int(self._flag_host.array[2:4].view(np.uint64)[0]) - relaxed_before
        return iterations, relaxed

    # -- queries --------------------------------------------------------------------------------

    def costs(self) -> np.ndarray:
        self._check_fault()
        return self._g.get().reshape(self._shape)

    def blocked(self) -> np.ndarray:
        self._check_fault()
        return self._blocked_d.get().astype(bool).reshape(self._shape)

    def cost_at(self, cell: Cell) -> int:
        self._check_fault()
        if not in_bounds(self._shape, cell):
            return int(INF)
        return int(self._g[int(cell[0]) * self._shape[1] + int(cell[1])].get())

    def path(self, start: Cell) -> np.ndarray:
        self._check_fault()
        start = (int(start[0]), int(start[1]))
        if self._shape == (0, 0) or not in_bounds(self._shape, start):
            return np.empty((0, 2), dtype=np.int32)
        with ck.DEVICE_LOCK:
            return self._path_locked(start, with_ctrl=False)

    def _path_locked(self, start: Cell, with_ctrl: bool) -> np.ndarray:
        """Launch the path kernel(s) from ``start`` and read the cells back (lock held).

        ``with_ctrl``: the first copy also brings the ctrl words of the fast launch queued
        before it (one copy, one synchronisation for a whole replanning step)."""
        w = self._shape[1]
        host, at = self._io_host, ck.IO_PATH
        chunks: list[np.ndarray] = []
        cur = start[0] * w + start[1]
        first = 0 if with_ctrl else at  # where the first copy starts in _io
        while True:
            self._launch_path(cur)
            guess = min(self._path_guess, self._path_cap)
            host.from_device(self._io, at + 2 + guess - first, offset=first)
            ck.synchronize()
            first = at
            count, status = int(host.array[at]), int(host.array[at + 1])
            if count > guess:
                host.from_device(self._io, count - guess, offset=at + 2 + guess)
                ck.synchronize()
            self._path_guess = max(256, 2 * count)
            cells = host.array[at + 2 : at + 2 + count].astype(np.int64)
            chunks.append(cells if not chunks else cells[1:])
            if status != 1:
                break
            cur = int(cells[-1])
        if status == 2:
            return np.empty((0, 2), dtype=np.int32)
        if status == 3:
            raise RuntimeError(f"g is not a consistent cost field on the way from {start}")
        flat = np.concatenate(chunks)
        return np.stack((flat // w, flat % w), axis=1).astype(np.int32)

    def _launch_path(self, cur: int) -> None:
        h, w = self._shape
        hw, start, cap = (np.int32(h), np.int32(w)), np.int32(cur), np.int32(self._path_cap)
        if self.path_mode == "walk":
            ck.kernel("path", "walk_path")((1,), (ck.THREADS,), (self._g, *hw, start,
                                                                 self._path_d, cap))  # fmt: skip
            return
        ck.kernel("path_tiles", "path_tiles")(
            (self._path_blocks,), (128,),
            (self._g, *hw, start, self._exits, self._segs, self._path_d, cap, self._path_ctrl,
             np.uint32(self._path_bar)),
        )  # fmt: skip
        self._path_bar = (self._path_bar + 2 * self._path_blocks) % 2**32

    @property
    def goal(self) -> Cell:
        return self._goal

    @property
    def shape(self) -> tuple[int, int]:
        return self._shape

    def device_bytes(self) -> int:
        """Bytes of device memory this planner's state holds."""
        arrays = [v for v in vars(self).values() if isinstance(v, cp.ndarray) and v.base is None]
        return int(sum(a.nbytes for a in arrays))
