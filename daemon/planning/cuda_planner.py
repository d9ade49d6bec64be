"""The cuda backend: EDS and DSS in CuPy raw kernels, bit-exact with the CPU backends.

Two variants (``kernels/``):

- ``fast`` (default, ``fast.cu``): every block of the device works on one planning call at a
  time. 32 x 32 tiles settle in shared memory; a tile is relaxed as soon as a neighbour's
  border change flags it (or in grid-wide rounds, ``sched=0``), so an EDS update works around
  the change; in ``update_and_path`` the same call then extracts the path, recomputing the
  tile exits only where g changed. The call writes statistics and path straight into
  page-locked host memory mapped into the device; the host polls its done word instead of
  synchronising. By default a resident loop (``cuda_resident.py``) serves the calls: the
  host posts a step into a mapped mailbox and pays no launch. With ``resident=False`` each
  call is a launch, replayed as a CUDA graph (the params and delta copied up, the launch).
- ``paper`` (``cuda_paper.py``, ``paper.cu``): Díaz-Toro et al.'s Figure 4 form, for
  comparison: read-only and write-only maps for g, pred and incon, one ``kernel_planner``
  launch per iteration and ``flag_stop`` read back after each.

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
from collections.abc import Callable

import cupy as cp
import numpy as np

from . import cuda_kernels as ck
from . import cuda_resident
from .cuda_launch import FastLaunch
from .cuda_paper import PaperForm
from .cuda_path import PathReader
from .grid import INF, Cell, in_bounds
from .interface import Planner, UpdateStats, checked_plan_input

VARIANTS = ("fast", "paper")
PATH_MODES = ("tiles", "walk")
"""``tiles``: path_tiles.cu, tile-to-tile jumps with the segments walked in parallel (default);
``walk``: path.cu, one warp walks every cell in a shared-memory window."""


class CudaPlanner(FastLaunch, PaperForm, PathReader, Planner):
    """EDS/DSS on one CUDA device; ``variant`` is ``fast`` or ``paper``.

    ``fast`` options (BENCHMARKS.md, "Planning on the GPU", compares them): ``scans`` the
    in-tile relaxation (0 Jacobi sweeps, 1 + row/column scans, 2 + diagonal scans: the
    default, fastest for large DSS), ``sched`` the relaxation's schedule (1 asynchronous: a
    tile is relaxed as soon as a neighbour flags it, the default; 0 grid-wide rounds),
    ``min_blocks`` blocks per SM the kernel is compiled for (1: 64 registers a thread),
    ``path_mode`` (``PATH_MODES``; with ``tiles`` the fast launch of ``update_and_path`` also
    extracts the path), ``resident`` (``fast``: a resident loop serves the calls, the
    default; else a launch per call, ``use_graph`` picking a replayed CUDA graph or direct
    launches). Calls are serialised on the device (``cuda_kernels.DEVICE_LOCK``): the
    persistent kernel needs every block resident.

    ``UpdateStats.iterations`` of ``fast``: grid-wide rounds (EDS raise and reset; with
    ``sched=0`` also the relaxation's), plus with ``sched=1`` the longest chain of tile visits
    of the relaxation, the rounds it stands in for.
    """

    def __init__(
        self,
        variant: str = "fast",
        *,
        scans: int = 2,
        sched: int = 1,
        min_blocks: int = 1,
        path_mode: str = "tiles",
        max_blocks: int | None = None,
        use_graph: bool = True,
        resident: bool = True,
        profile: bool = False,
    ) -> None:
        if variant not in VARIANTS:
            raise ValueError(f"unknown variant {variant!r}; choose one of {VARIANTS}")
        if path_mode not in PATH_MODES:
            raise ValueError(f"unknown path_mode {path_mode!r}; choose one of {PATH_MODES}")
        self.path_mode = path_mode
        self.use_graph = use_graph  # fast: replay each step as a captured CUDA graph
        # The loop serves fused calls; with the path by its own launch (walk) every step would
        # stop it for that launch and start it again.
        self.resident = resident and variant == "fast" and path_mode == "tiles"
        self._loop: cuda_resident.ResidentLoop | None = None
        self.max_blocks = max_blocks  # caps the persistent grid (experiments; None: all resident)
        self.variant = variant
        self.name = f"cuda-{variant}"
        self._shape: tuple[int, int] = (0, 0)
        self._goal: Cell = (0, 0)
        self._fault: BaseException | None = None
        # Host work that may run while the device serves a fast call (set by the caller, e.g.
        # fallback.FallbackPlanner's copies of the change for its mirror): called once, after
        # the call is posted or launched and before the wait for it.
        self.while_waiting: Callable[[], None] | None = None
        self.last_stats: UpdateStats | None = None
        self._defines = tuple(
            f"{k}={int(v)}"
            for k, v in (("SCANS", scans), ("SCHED", sched), ("MIN_BLOCKS", min_blocks))
        )
        self._defines += ("PROFILE=1",) if profile else ()  # phase_ns
        # A call's results, written by fast.cu itself (mapped): the ctrl words, the done word,
        # then the path (see _allocate); the path kernels' results are copied here too.
        self._io_host = ck.Pinned(ck.IO_PATH + 2 + 2 * 1024, np.int32, mapped=True)
        # A call's input: the params words, then the delta (see _call_resident). Mapped: the
        # resident loop's mailbox (its block 0 copies the params and the checked, encoded
        # delta into ``_params`` on the device); a launched call copies it all there first.
        # Never read in place by every block: 100+ blocks reading the same host words wait
        # ~100 µs for PCIe (BENCHMARKS.md, "Planning on the GPU").
        self._stage = ck.Pinned(ck.PARAMS + ck.GRAPH_DELTA, np.int32, mapped=True)
        self._stage_views: tuple[np.ndarray, ...] = (np.empty(0),)  # see _call_resident
        self._pairs = (np.empty(0), np.empty((0, 2)))  # see _path_locked
        self._result: tuple[int, ...] = ()  # the last fast call's result words (_call_fast)
        self._seq = 0  # the sequence number of the last fast call (its done word)
        self._params = self._delta = cp.zeros(0, dtype=np.int32)
        self._graph: cp.cuda.graph.Graph | None = None
        self._path_guess = 256
        self._slot = 0  # paper: which flag_stop slot the next launch writes
        # fast, last call: in-tile sweeps summed over tiles, cells raised to INF, tiles run,
        # tiles whose path exits were recomputed (update_and_path; the rest were reused).
        self.sweeps = self.raised_cells = self.tiles = self.exit_tiles = 0

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
        self._drop_loop()  # it holds the old buffers
        cuda_resident.evict()  # the fills below are kernels
        h, w = shape
        n = h * w
        self._shape = shape
        self._blocked_d = cp.zeros(n, dtype=np.uint8)
        self._g = cp.full(n, INF, dtype=np.int32)
        self._path_cap = int(min(n, 4 * (h + w) + 1024))
        # One device buffer holds fast.cu's ctrl words (barrier count, statistics; the launch
        # copies them into _io_host itself) and then the path kernels' output, copied back.
        self._io = cp.zeros(ck.IO_PATH + 2 + 2 * self._path_cap, dtype=np.int32)
        self._ctrl = self._io[: ck.IO_PATH].view(np.uint32)
        self._path_d = self._io[ck.IO_PATH :]
        self._io_host.reserve(ck.IO_PATH + 2 + 2 * self._path_cap)
        self._set_params_size(ck.PARAMS + ck.GRAPH_DELTA)
        tiles = -(-h // ck.TILE) * -(-w // ck.TILE)
        self._tiles = tiles
        # Path by tile jumps (path_exits.cuh): 124 border exits per tile, kept between steps
        # (fast.cu recomputes only stale tiles), and the segments of one extraction.
        self._exits = cp.zeros(2 * 124 * tiles, dtype=np.int32)
        self._segs = cp.zeros(4 * self._path_cap, dtype=np.int32)
        if self.path_mode == "tiles":
            self._path_ctrl = cp.zeros(64, dtype=np.uint32)
            self._path_bar = 0  # its barrier count: 2 barriers x blocks per launch
            k = ck.kernel("path_tiles", "path_tiles")
            sms = int(cp.cuda.Device().attributes["MultiProcessorCount"])
            self._path_blocks = int(min(tiles, ck.resident_blocks(k, 128), 8 * sms))
        if self.variant == "fast":
            self._raised = cp.zeros(n, dtype=np.uint8)
            # fast.cu's tile flags: ping, pong, seeds, stale exits (all stale at first), depth.
            self._flags = cp.zeros(5 * tiles, dtype=np.uint32)
            self._flags[3 * tiles : 4 * tiles] = 1
            # Both kernels run with this grid, all of whose blocks must be resident at once.
            fits = min(ck.resident_blocks(self._k_fast()), ck.resident_blocks(self._k_loop()))
            self._blocks = int(min(tiles, fits, self.max_blocks or tiles))
        else:
            self._allocate_paper(n)

    def _set_params_size(self, size: int) -> None:
        """A device buffer for the params words and a delta of up to ``size - PARAMS`` cells."""
        self._drop_loop()
        self._params = cp.zeros(size, dtype=np.int32)
        self._delta = self._params[ck.PARAMS :]  # the paper's kernels take the delta alone
        self._graph = None  # it holds the buffers' addresses

    def _stage_delta(self, cells: np.ndarray, blocked: np.ndarray) -> int:
        """The delta into the stage after the params words, encoded and checked here
        (``encode_delta``), for a launched call (fast: ``_launch_fast``; paper:
        ``_run_paper``), which copies it up. Returns its length. The resident loop's delta
        goes raw (``_call_resident``)."""
        h, w = self._shape
        cells = np.asarray(cells)
        self._grow_stage(ck.PARAMS + cells.size, cells.size)  # encoding: a word a cell at most
        return ck.encode_delta(cells, blocked, h * w, out=self._stage.array[ck.PARAMS :]).size

    def _grow_stage(self, words: int, n: int) -> None:
        """Room in the stage for ``words`` (the params and a delta) and on the device for a
        delta of ``n`` cells. A stage that moves stops the resident loop (it polls the stage)
        and drops the graph (it holds the stage's address); so does a new params buffer."""
        if words > self._stage.count:
            self._drop_loop()
            self._stage.reserve(words)
            self._graph = None
        if ck.PARAMS + n > self._params.size:
            self._set_params_size(2 * (ck.PARAMS + n))

    def _drop_loop(self) -> None:
        if self._loop is not None:
            self._loop.stop()
            self._loop = None

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
            ck.synchronize()  # a resident loop runs on its own stream: the map is there first
            return self._run(False, t0)

    def update(self, cells: np.ndarray, blocked: np.ndarray) -> UpdateStats:
        return self._change(cells, blocked, eds=True)

    def replan(self, cells: np.ndarray, blocked: np.ndarray) -> UpdateStats:
        return self._change(cells, blocked, eds=False)

    def _change(self, cells: np.ndarray, blocked: np.ndarray, eds: bool) -> UpdateStats:
        t0 = time.perf_counter()
        self._check_fault()
        self._require_plan()
        with ck.DEVICE_LOCK:
            return self._run(eds, t0, cells, blocked)

    def _run(
        self,
        eds: bool,
        t0: float,
        cells: np.ndarray | None = None,
        blocked: np.ndarray | None = None,
    ) -> UpdateStats:
        if self.variant == "fast":
            self._call_fast(eds, cells, blocked)
            iterations, touched = self._read_fast_stats()
        else:
            n = 0 if cells is None else self._stage_delta(cells, blocked)
            iterations, touched = self._run_paper(eds, n)
        stats = UpdateStats(iterations, touched, (time.perf_counter() - t0) * 1e3)
        self.last_stats = stats
        return stats

    def update_and_path(
        self, cells: np.ndarray, blocked: np.ndarray, start: Cell, *, full: bool = False
    ) -> tuple[UpdateStats, np.ndarray]:
        """One launch that repairs the field and extracts the path (``fast`` with
        ``path_mode="tiles"``; with ``walk`` the path kernel is queued right behind it), with
        statistics and path copied back and a single synchronisation. ``paper`` syncs per
        iteration anyway and takes the interface's default."""
        if self.variant != "fast":
            stats, path = super().update_and_path(cells, blocked, start, full=full)
            self.last_stats = stats  # the whole step's, as for fast
            return stats, path
        # Every walking step runs this: checks inline rather than in helpers (a cold Python call
        # costs 1-2 µs after the caller's other work; BENCHMARKS.md).
        t0 = time.perf_counter()
        if self._fault is not None:
            self._check_fault()
        h, w = self._shape
        if not h:
            self._require_plan()
        y, x = int(start[0]), int(start[1])
        inside = 0 <= y < h and 0 <= x < w
        fused = inside and self.path_mode == "tiles"
        with ck.DEVICE_LOCK:
            self._call_fast(not full, cells, blocked, y * w + x if fused else -1)
            if inside:
                path = self._path_locked((y, x), fused=fused)
            else:
                path = np.empty((0, 2), dtype=np.int32)
            iterations, touched = self._read_fast_stats()
        stats = UpdateStats(iterations, touched, (time.perf_counter() - t0) * 1e3)
        self.last_stats = stats
        return stats, path

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
            if self.resident:  # which implies the fused path (path_mode "tiles")
                # A call with no change: the loop extracts the path, no launch.
                self._call_fast(True, None, None, start[0] * self._shape[1] + start[1])
                return self._path_locked(start, fused=True)
            return self._path_locked(start)

    def phase_ns(self) -> np.ndarray:
        """With ``profile=True``, after a fused ``update_and_path``: ns of the launch's phases as
        block 0 saw them (fast.cu PROFILE): init (the params read), delta and seeds, EDS raise
        and reset, the relaxation, the stale tiles' exits, the hops, block 0's segments."""
        stamps = self._io_host.array[ck.P_STAMPS : ck.P_STAMPS + 8].view(np.uint32)
        return (np.diff(stamps.astype(np.int64)) % 2**32).astype(np.int64)

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
