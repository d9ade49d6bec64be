"""The cuda backend: EDS and DSS in CuPy raw kernels, bit-exact with the CPU backends.

Two variants (``kernels/``):

- ``fast`` (default, ``fast.cu``): every block of the device works on one planning call at a
  time. 32 x 32 tiles settle in shared memory; a tile is relaxed as soon as a neighbour's
  border change flags it, so an EDS update works around the change; in ``update_and_path``
  the same call then extracts the path, recomputing the tile exits only where g changed. A
  resident loop (``resident.py``, ``call.py``) serves the calls: the host posts a step into a
  mapped mailbox and pays no launch; the call writes statistics and path straight into
  page-locked host memory mapped into the device, and the host polls its done word.
- ``paper`` (``paper.py``, ``paper.cu``): Díaz-Toro et al.'s Figure 4 form, for comparison:
  read-only and write-only maps for g, pred and incon, one ``kernel_planner`` launch per
  iteration and ``flag_stop`` read back after each.

EDS semantics are the CPU's: newly blocked cells are raised to INF, and so is every cell
all of whose supporting neighbours (g[n] + cost == g[v]) are raised — exactly the cells whose
cost must rise (``fast``; ``paper`` raises the whole subtree of its stored pred map, a
superset); then raised and newly freed cells are re-seeded from their neighbours and
everything is relaxed until nothing changes. Every value is an integer path cost, so the
fixpoint is the exact field, equal to the CPU's cell for cell whatever the order of relaxation.
As on the CPU, ``fast``'s repair gives up once it has raised more than ``cut_over`` cells (a
wall across the route raises the whole shadow behind it): the device decides at the end of a
raise round, with no host round trip (``fast.cu``), and the same call keeps every cell whose
old g lies below the least g the change can reach and relaxes the rest from there
(``kernels/cut_over.cuh``, LPA*'s rule), instead of from the goal; ``cut_cells`` tells
whether the last call gave up.

``fast``'s EDS repair is focused on the user (LPA*'s and D* Lite's keys g + h(user, ·), per
32 x 32 tile, ``fast.cu``'s header): a walking step settles the tiles between the user and the
goal whose key can still improve the user's path and defers the rest to later calls. The
contract is the CPU's (``cpu/repair.py``): the path read in a step (``update_and_path``,
``path``) is ``reference_path`` of the current map, tie for tie, and its cost the user's exact
g; ``costs()`` and ``cost_at`` are exact after ``settle()``, which they run themselves. DSS is
never focused.

``path`` runs on the device with the rule of ``dijkstra.reference_path`` (``path_exits.cuh``:
tile-to-tile jumps, segments walked in parallel); only the path's cells come back.

A device failure raises one of ``errors.device_errors()``; the planner is then unusable (a
CUDA fault is sticky: every later call on the context fails too) and the caller, which owns
the map, builds a CPU planner from it. Test hook: ``inject_fault(exc)`` makes every later
public call raise ``exc`` before touching the device, as a sticky fault would.
"""

from __future__ import annotations

import time

import cupy as cp
import numpy as np

from ..field import FieldPlanner
from ..grid import INF, Cell, checked_plan_input, in_bounds
from ..interface import UpdateStats
from . import abi, device, posting, resident
from .call import R_COUNT, R_REJECT, R_STATUS, RESULT_WORDS, FastCall
from .paper import PaperForm
from .path import PathReader

VARIANTS = ("fast", "paper")
PATH_THREADS = 128
"""Threads of a path_tiles block (its __launch_bounds__)."""
CUT_OVER = 0.5
"""How many cells an EDS repair (``fast``) may raise per row and column of the map before the
call gives the repair up (the cut-over, cut_over.cuh): the limit is ``CUT_OVER * (h + w)``
cells, or ``CUT_OVER_AREA`` of the cells where that is more. A plan from scratch costs about as
many tile visits in a row as the map is tiles across, a raise about as many as the cells it
raises. On the H100 0.5 gave the lowest p99 at 400² and 1000² without raising the 2000² median;
again 2026-11-27 (400², four scenarios, 0.5 / 0.25 / 0.35 twice each on one host), 0.25 and
0.35 gave no lower p99 and no shorter walk. Read when a planner is made."""
CUT_OVER_AREA = 0.001
"""The least limit of an EDS repair's raise, as a share of the map's cells (see ``CUT_OVER``):
4,000 cells at 2000², the limit measured best there; below ``CUT_OVER * (h + w)`` up to 1000²."""
DELTA_ROOM = 1 / 16
"""The share of a new map's cells that its stage (the mailbox) and params buffer have room
for, at least ``DELTA_ROOM_MIN`` cells and at most all of them. A delta beyond the room moves
the stage, which stops the resident loop, allocates page-locked memory and launches the loop
again: with room for only 1,024 cells, a wall seen whole (1,000-9,000 cells at 400²) made
those steps a walk's slowest. The benchmark's largest deltas stay inside it (~9,000 cells at
400², room 10,000; 30,000 at 2000², room 250,000: 2.3 MB page-locked)."""
DELTA_ROOM_MIN = 4096
FOCUSED = True
"""Whether ``fast``'s EDS repair is focused on the user (``fast.cu``); False: every call
settles the whole field, as before the focused repair. Read when a planner is made, so a
benchmark can compare the two."""


class CudaPlanner(FastCall, PaperForm, PathReader, FieldPlanner):
    """EDS (``dss=False``) or DSS on one CUDA device; ``variant`` is ``fast`` or ``paper``.

    Calls are serialised on the device (``device.DEVICE_LOCK``): the resident loop needs every
    block resident. ``UpdateStats.iterations`` of ``fast``: grid-wide rounds (EDS raise and
    reset) plus the longest chain of tile visits of the relaxation, the rounds it stands in for.
    ``cut_over`` (``fast``): the cells an EDS repair may raise per row and column of the map
    before the call gives the repair up and relaxes from below the change (default ``CUT_OVER``;
    ``math.inf``: never). ``focused`` (``fast`` EDS, default ``FOCUSED``): a walking step's
    repair settles only what the user's path needs and defers the rest (``settle``).
    """

    backend = "cuda"

    def __init__(
        self,
        variant: str = "fast",
        *,
        dss: bool = False,
        cut_over: float | None = None,
        focused: bool | None = None,
    ) -> None:
        if variant not in VARIANTS:
            raise ValueError(f"unknown variant {variant!r}; choose one of {VARIANTS}")
        self.variant = variant
        super().__init__(dss)
        self._cut_over_rate = CUT_OVER if cut_over is None else cut_over
        self.focused = (FOCUSED if focused is None else focused) and not dss
        self.cut_over = 1  # in cells, set with the map's size
        self._loop: resident.Slot | None = None  # this planner's place in the device's loop
        self._shape: tuple[int, int] = (0, 0)
        self._goal: Cell = (0, 0)
        self._fault: BaseException | None = None
        self.last_stats: UpdateStats | None = None
        # A call's results, written by fast.cu itself (mapped): the ctrl words, the done word,
        # then the path (see _allocate); the path kernel's results are copied here too.
        self._io_host = device.Pinned(abi.IO_PATH + 2 + 2 * 1024, np.int32, mapped=True)
        # A call's input: the params words, then the delta (see FastCall._call_fast). Mapped:
        # the resident loop's mailbox (its block 0 copies the params and the checked, encoded
        # delta into ``_params`` on the device). Never read in place by every block: 100+
        # blocks reading the same host words wait ~100 µs for PCIe.
        self._stage = device.Pinned(abi.PARAMS + 1024, np.int32, mapped=True)
        self._stage_views: tuple[np.ndarray, ...] = (np.empty(0),)  # see _call_fast
        self._pairs = (np.empty(0), np.empty((0, 2)))  # see _path_locked
        self._result: tuple[int, ...] = ()  # the last fast call's result words (_call_fast)
        self._seq = 0  # the sequence number of the last fast call (its done word)
        self._params = self._delta = cp.zeros(0, dtype=np.int32)
        self._path_guess = 256
        self._slot = 0  # paper: which flag_stop slot the next launch writes
        # fast, last call: in-tile sweeps summed over tiles, cells raised to INF, tiles run,
        # tiles whose path exits were recomputed (update_and_path; the rest were reused), and
        # the cells raised when the repair gave up (cut over; 0: it did not).
        self.sweeps = self.raised_cells = self.tiles = self.exit_tiles = self.cut_cells = 0
        # The cell the last EDS path was read from (a step with no path read stays focused on
        # it; -1: none), and whether a focused call may have deferred tiles since the last
        # settle.
        self._focus = -1
        self._unsettled = False

    # -- test hook ----------------------------------------------------------------------------

    def inject_fault(self, exc: BaseException) -> None:
        """Make every later public call raise ``exc`` (tests of the caller's CPU fallback)."""
        self._fault = exc

    def _check_fault(self) -> None:
        if self._fault is not None:
            raise self._fault

    # -- state ----------------------------------------------------------------------------------

    def _allocate(self, shape: tuple[int, int]) -> None:
        self._drop_loop()  # it holds the old buffers
        resident.evict()  # the fills below are kernels
        h, w = shape
        n = h * w
        self._shape = shape
        limit = max(1.0, self._cut_over_rate * (h + w), CUT_OVER_AREA * n)
        self.cut_over = int(min(n, limit))
        self._blocked_d = cp.zeros(n, dtype=np.uint8)
        self._g = cp.full(n, INF, dtype=np.int32)
        self._path_cap = int(min(n, 4 * (h + w) + 1024))
        # One device buffer holds fast.cu's ctrl words (barrier count, statistics; the call
        # copies them into _io_host itself) and then the path kernel's output, copied back.
        self._io = cp.zeros(abi.IO_PATH + 2 + 2 * self._path_cap, dtype=np.int32)
        self._ctrl = self._io[: abi.IO_PATH].view(np.uint32)
        self._path_d = self._io[abi.IO_PATH :]
        self._io_host.reserve(abi.IO_PATH + 2 + 2 * self._path_cap)
        room = int(min(n, max(DELTA_ROOM_MIN, DELTA_ROOM * n)))
        self._stage.reserve(abi.PARAMS + 4 * ((9 * room + 15) // 16))  # as _call_fast stages
        self._set_params_size(abi.PARAMS + room)
        tiles = -(-h // abi.TILE) * -(-w // abi.TILE)
        # Path by tile jumps (path_exits.cuh): the border exits of every tile, kept between
        # steps (fast.cu recomputes only stale tiles), and the segments of one extraction.
        self._exits = cp.zeros(2 * abi.BORDER * tiles, dtype=np.int32)
        self._segs = cp.zeros(4 * self._path_cap, dtype=np.int32)
        self._path_ctrl = cp.zeros(abi.PATH_CTRL, dtype=np.uint32)
        self._path_bar = 0  # its barrier count: 2 barriers x blocks per launch
        k = device.kernel("path_tiles", "path_tiles")
        sms = int(cp.cuda.Device().attributes["MultiProcessorCount"])
        self._path_blocks = int(min(tiles, device.resident_blocks(k, PATH_THREADS), 8 * sms))
        if self.variant == "fast":
            self._raised = cp.zeros(n, dtype=np.uint8)
            # fast.cu's tile flags: ping, pong, seeds, stale exits (all stale at first), depth,
            # deferred by a focused repair, and the deferred tiles' bounds (INF: none).
            self._flags = cp.zeros(abi.FLAG_SEGMENTS * tiles, dtype=np.uint32)
            self._flags[3 * tiles : 4 * tiles] = 1
            self._flags[6 * tiles : 7 * tiles] = INF
        else:
            self._allocate_paper(n)

    def _set_params_size(self, size: int) -> None:
        """A device buffer for the params words and a delta of up to ``size - PARAMS`` cells."""
        self._drop_loop()
        self._params = cp.zeros(size, dtype=np.int32)
        self._delta = self._params[abi.PARAMS :]  # the paper's kernels take the delta alone

    def _stage_delta(self, cells: np.ndarray, blocked: np.ndarray) -> int:
        """paper: the delta into the stage after the params words, encoded and checked here
        (``encode_delta``), for ``_run_paper`` to copy up. Returns its length."""
        h, w = self._shape
        cells = np.asarray(cells)
        self._grow_stage(abi.PARAMS + cells.size, cells.size)  # a word a cell at most
        return device.encode_delta(cells, blocked, h * w, out=self._stage.array[abi.PARAMS :]).size

    def _grow_stage(self, words: int, n: int) -> None:
        """Room in the stage for ``words`` (the params and a delta) and on the device for a
        delta of ``n`` cells. A stage that moves stops the resident loop (it polls the stage);
        so does a new params buffer."""
        if words > self._stage.count:
            self._drop_loop()
            self._stage.reserve(words)
        if abi.PARAMS + n > self._params.size:
            self._set_params_size(2 * (abi.PARAMS + n))

    def _drop_loop(self) -> None:
        """Give this planner's slot back before its buffers change, and stop the device's
        loop: what follows allocates, fills (a kernel, which would wait for the SMs the loop
        holds until it ends idle: the 200 ms steps of the first device run) or frees memory
        the loop may still hold (page-locked allocations and frees may synchronise with the
        device). Rare: a new map or a delta larger than any before."""
        if self._loop is not None:
            self._loop.stop()
            self._loop = None
        resident.evict()

    def _require_plan(self) -> None:
        if self._shape == (0, 0):
            raise RuntimeError("call plan(blocked, goal) before update")

    # -- planning -------------------------------------------------------------------------------

    def plan(self, blocked: np.ndarray, goal: Cell) -> UpdateStats:
        t0 = time.perf_counter()
        self._check_fault()
        blocked, shape, goal = checked_plan_input(blocked, goal)
        with device.DEVICE_LOCK:
            if shape != self._shape:
                self._allocate(shape)
            self._goal = goal
            self._blocked_d.set(np.ascontiguousarray(blocked, dtype=np.uint8).ravel())
            device.synchronize()  # a resident loop runs on its own stream: the map is there first
            self._focus, self._unsettled = -1, False  # a plan from scratch defers nothing
            return self._run(False, t0)

    def _repair(self, cells: np.ndarray, blocked: np.ndarray) -> UpdateStats:
        return self._change(cells, blocked, eds=True)

    def _recompute(self, cells: np.ndarray, blocked: np.ndarray) -> UpdateStats:
        return self._change(cells, blocked, eds=False)

    def _change(self, cells: np.ndarray, blocked: np.ndarray, eds: bool) -> UpdateStats:
        t0 = time.perf_counter()
        self._check_fault()
        self._require_plan()
        with device.DEVICE_LOCK:
            return self._run(eds, t0, cells, blocked)

    def _run(
        self,
        eds: bool,
        t0: float,
        cells: np.ndarray | None = None,
        blocked: np.ndarray | None = None,
    ) -> UpdateStats:
        if self.variant == "fast":
            self._call_fast(eds, cells, blocked, focus=self._focus if eds else -1)
            iterations, touched = self._read_fast_stats()
        else:
            n = 0 if cells is None else self._stage_delta(cells, blocked)
            iterations, touched = self._run_paper(eds, n)
        stats = UpdateStats(iterations, touched, (time.perf_counter() - t0) * 1e3)
        self.last_stats = stats
        return stats

    def update_and_path(
        self, cells: np.ndarray, blocked: np.ndarray, start: Cell
    ) -> tuple[UpdateStats, np.ndarray]:
        """``fast``: one call that repairs (EDS) or recomputes (DSS) the field and extracts the
        path, statistics and path read back after a single wait; the steps that several
        threads call at once share posts (``combine.py``). ``paper`` syncs per iteration
        anyway and takes the interface's default."""
        if self.variant != "fast":
            stats, path = super().update_and_path(cells, blocked, start)
            self.last_stats = stats  # the whole step's, as for fast
            return stats, path
        # Posted alone when the device is free, else with the steps other threads call
        # meanwhile, as the next post (posting.py).
        return posting.STEPS.call((self, cells, blocked, start, time.perf_counter()))

    def _stage_step(self, cells: np.ndarray, blocked: np.ndarray, start: Cell) -> tuple:
        """A walking step's call staged for a post (lock held): (start, seq, delta length,
        cells, blocked, flat start). ``update_and_path`` posts it alone, ``batch.py`` with
        other planners' steps; ``_finish_step`` reads it once done."""
        # Every walking step runs this: checks inline rather than in helpers (a cold Python call
        # costs 1-2 µs right after the caller's other work).
        if self._fault is not None:
            self._check_fault()
        h, w = self._shape
        if not h:
            self._require_plan()
        y, x = int(start[0]), int(start[1])
        cell = y * w + x if 0 <= y < h and 0 <= x < w else -1
        if cell >= 0 and self.focused:
            self._focus = cell
        seq, n = self._stage_fast(not self.dss, cells, blocked, cell, self._focus)
        return (y, x), seq, n, cells, blocked, cell

    def _finish_step(self, step: tuple, t0: float) -> tuple[UpdateStats, np.ndarray]:
        """The staged step's statistics and path, its call done (lock held); the common case
        (delta taken, path whole in the mapped buffer) in line: a helper's frame costs ~1 µs."""
        start, _, _, cells, blocked, cell = step
        self._result = st = RESULT_WORDS.unpack_from(self._io_host.view)
        if st[R_REJECT]:  # refused: raised, or sorted and called again
            self._finish_fast(not self.dss, cells, blocked, cell, False, self._focus)
            st = self._result
        if cell < 0:
            path = np.empty((0, 2), dtype=np.int32)
        elif st[R_STATUS] == abi.PATH_DONE and self._pairs[0] is self._io_host.array:
            path = self._pairs[1][: st[R_COUNT]].copy()  # as _path_locked reads it
        else:
            path = self._path_locked(start, fused=True)
        raised = st[abi.C_RAISED]
        self.sweeps, self.raised_cells, self.tiles = st[abi.C_SWEEPS], raised, st[abi.C_TILES]
        self.exit_tiles, self.cut_cells = st[abi.C_EXITS], st[abi.C_CUT]
        touched = raised + st[abi.C_CHANGED]
        stats = UpdateStats(st[abi.C_ROUNDS], touched, (time.perf_counter() - t0) * 1e3)
        self.last_stats = stats
        return stats, path

    # -- queries --------------------------------------------------------------------------------

    def settle(self) -> UpdateStats:
        """Finish a focused repair everywhere (``fast``: one call with no change and no
        focus); afterwards the stored field is exact. No call when nothing can be pending."""
        t0 = time.perf_counter()
        self._check_fault()
        self._require_plan()
        if self.variant != "fast" or not self._unsettled:
            return UpdateStats(0, 0, (time.perf_counter() - t0) * 1e3)
        with device.DEVICE_LOCK:
            self._call_fast(True, None, None)
            self._unsettled = False
            # The last step's statistics (raised_cells, cut_cells, tiles, ...) stay: a query
            # that settles is no step.
            st = self._result
            iterations, touched = st[abi.C_ROUNDS], st[abi.C_RAISED] + st[abi.C_CHANGED]
        return UpdateStats(iterations, touched, (time.perf_counter() - t0) * 1e3)

    def deferred_tiles(self) -> int:
        """Tiles a focused repair (``fast``) left for later calls (0 after ``settle``)."""
        self._check_fault()
        if self.variant != "fast" or self._shape == (0, 0):
            return 0
        tiles = self._flags.size // abi.FLAG_SEGMENTS
        return int(cp.count_nonzero(self._flags[5 * tiles : 6 * tiles]))

    def costs(self) -> np.ndarray:
        self._check_fault()
        if self._unsettled:
            self.settle()
        return self._g.get().reshape(self._shape)

    def blocked(self) -> np.ndarray:
        self._check_fault()
        return self._blocked_d.get().astype(bool).reshape(self._shape)

    def cost_at(self, cell: Cell) -> int:
        self._check_fault()
        if not in_bounds(self._shape, cell):
            return int(INF)
        if self._unsettled:
            self.settle()
        return int(self._g[int(cell[0]) * self._shape[1] + int(cell[1])].get())

    def path(self, start: Cell) -> np.ndarray:
        self._check_fault()
        start = (int(start[0]), int(start[1]))
        if self._shape == (0, 0) or not in_bounds(self._shape, start):
            return np.empty((0, 2), dtype=np.int32)
        with device.DEVICE_LOCK:
            if self.variant == "fast":
                # A call with no change: the loop extracts the path, no launch.
                cell = start[0] * self._shape[1] + start[1]
                self._call_fast(True, None, None, cell, focus=cell if self.focused else -1)
                return self._path_locked(start, fused=True)
            return self._path_locked(start)

    def device_bytes(self) -> int:
        """Bytes of device memory this planner's state holds."""
        arrays = [v for v in vars(self).values() if isinstance(v, cp.ndarray) and v.base is None]
        return int(sum(a.nbytes for a in arrays))
