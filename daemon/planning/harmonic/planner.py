"""Hong & DeSouza's harmonic potential field behind guidebelt's planner interface.

``plan`` builds the field of eq. (1) — goal 0, obstacles 1, free cells relaxed to their four
neighbours' mean — kept as ``w = −ln(1 − u)`` (``relax.py`` says why: no plateau at any grid
size); ``update`` applies the map's changes and relaxes again from the last field (warm
start); ``path(start)`` is the paper's descent over Idx, the neighbour of lowest potential.

Contract (not a cost-to-go: the field is not a distance, and its paths are not shortest):
- the descent from every cell the goal reaches (8-connected, the nine-point stencil of
  ``relax.py``) ends at the goal, and never enters a blocked cell;
- a cell the goal does not reach gets no path (empty), never a wrong one: the descent only
  ever steps to a strictly lower free cell, so it cannot climb into an obstacle or loop;
- convergence: ``plan`` (and ``converge``) relax until the residual, the largest change a
  sweep would make to any reachable cell's ``w`` (log units, i.e. the relative change of
  ``1 − u``), is below ``tol`` (1e-4), checked every 5 sweeps. A replanning step
  (``update``) is bounded: at most ``step_cap`` (20) sweeps at omega 1, stopping at ``tol``
  or, once ``step_sweeps`` (10) are done, at the first check that finds no pit — no
  reachable cell without a strictly lower neighbour (``relax.has_pit``). If pits (or free
  cells with no value yet) are left, their basins are filled (``fill.py``: priority-flood
  + ε, a pass over the basins, not sweeps over the grid). So after every step every
  reachable cell has a strictly lower neighbour: the descent from it reaches the goal and
  never enters a blocked cell. What a step leaves of the residual the next steps go on
  relaxing from (the paper's loop relaxes without end, §II-B); ``converge`` finishes it to
  ``tol``, and a warm field converged so equals a cold plan within the tolerance's bound
  (the tests': 5e-3 on the CPU, 1e-2 on the GPU). If a descent still stops short from a
  reachable cell, the planner relaxes with a 10 times tighter tolerance (at most 2000
  sweeps, once per field) and tries once more, and counts it in ``retries``. A plan's or
  ``converge``'s relaxation that has not converged after a quarter of its budget goes on at
  omega 1 (Gauss–Seidel).
- ``cost_at(cell)`` is the 10/14 cost of ``path(cell)`` (INF if none), as for ``visgraph``;
  ``costs_within`` the same over a window (the escape from the margin reads it).

First field of a cold plan (``init``): ``distance`` (default) starts from 0.05 per
8-connected step from the goal, a field that already descends from every reachable cell;
``paper`` from the paper's "median range" (u = 0.5). The relaxation (``order``): ``rb``,
red–black SOR (omega 1.3), the GPU's; ``rows``, the paper's row-wise Gauss–Seidel (§II-A);
``jacobi``, eq. (1) as written.

A step whose change frees nothing but may have cut cells off starts its relaxation on the
newly blocked cells while the host searches for the cells cut off (``overlap``, the CUDA
engine's default where the host searches; ``_start_early`` says why the field is the same).
Every step's fill is launched right behind its sweeps (``fill_behind``; the CUDA engine gates
it on the device by the sweeps' pit count), so a step waits once.

``UpdateStats``: ``iterations`` = sweeps, ``cells_touched`` = sweeps × reachable cells;
``filled``: the basin cells the last step's fill took (0 when it needed none).
"""

from __future__ import annotations

import time
from collections.abc import Callable

import numba
import numpy as np

from ..grid import INF, Cell, checked_plan_input, checked_update_input, in_bounds, path_cost
from ..interface import GlobalPlanner, UpdateStats
from . import fill as fl
from . import relax as rx
from .reach import Reach, padded_cells

TOL = 1e-4
"""Residual (log units) below which the field counts as converged."""
INIT_SLOPE = 0.05
"""``w`` per 8-connected step of the ``distance`` first guess."""
COLD_SWEEPS = 400_000
WARM_SWEEPS = 20_000
RETRY_SWEEPS = 2_000
BAND_ITERATIONS = 15
"""Rubber-band iterations a ``band`` call runs (it goes on from the last call's band)."""
STEP_SWEEPS = 10
"""Sweeps a replanning step does before a field without a pit may end it."""
STEP_CAP = 20
"""Sweeps after which a replanning step fills the basins of the pits left, and ends. 10 and
20, not 20 and 40: the fill, not the sweeps, keeps a step's field free of pits, and a sweep
costs 11 µs at 400² and 31 µs at 2000² on the H100 (courtyard walk, 60 steps, 20/40 against
10/20: 400² step median 1.91 → 1.84 ms, 2000² p99 20.6 → 12.3 ms; fills on 6 steps of 60
instead of 10 at 2000², on 49 instead of 42 at 400²)."""
STEP_OMEGA = 1.0
"""A replanning step sweeps at omega 1 (Gauss–Seidel), not the engine's 1.3: over-relaxing
drops cells of a filled basin's gentle slope below their lowest neighbour, and the next step
fills again (H100, 2000² courtyard walk, fill ε 0.05: fills on 50 of 60 steps at 1.3, on 9 at
1; step median 13.1 → 2.26 ms). Plans and ``converge`` keep the engine's omega."""
DEVICE_SEARCH_CELLS = 1 << 20
"""Padded maps from this many cells on search the whole map for the reach on the device
(``CudaField.reach_search``), smaller ones on the host. H100, the bench walk's whole-map
searches: at 400² the device's search took 1.05 ms where the host's breadth-first search and
its diff took ~0.3; at 2000² the device's 6.3 ms against ~40 ms on the host. Between the two
the crossing is interpolated (~1000²), not measured."""
_EMPTY = np.empty((0, 2), dtype=np.int32)


@numba.njit(cache=True, nogil=True)
def _map_cells(flat: np.ndarray, width: int) -> np.ndarray:
    """A descent's padded flat cells as map cells, ``(k, 2) int32``: numpy's divide, modulo,
    stack and cast took ~20 µs a 600-cell path (dev VM), on every path read of a step."""
    out = np.empty((flat.size, 2), dtype=np.int32)
    for k in range(flat.size):
        out[k, 0] = flat[k] // width - 1
        out[k, 1] = flat[k] % width - 1
    return out


class HarmonicPlanner(GlobalPlanner):
    is_distance = False
    """The field is not a cost-to-go: compare and the property tests judge it by its own
    contract (descent reaches the goal), not by the reference Dijkstra's costs."""

    def __init__(self, engine, *, init: str = "distance", tol: float = TOL, name: str = "",
                 step_sweeps: int | None = STEP_SWEEPS) -> None:  # fmt: skip
        """``step_sweeps`` None: every replanning step relaxes to ``tol``."""
        if init not in ("distance", "paper"):
            raise ValueError(f"unknown init {init!r}; choose distance or paper")
        self.engine = engine
        self.backend = engine.backend
        self.init = init
        self.tol = float(tol)
        self.step_sweeps = step_sweeps
        self.step_cap = STEP_CAP
        self.filled = 0
        """Basin cells the last step's fill took (0: the sweeps left no pit)."""
        self.fills = 0
        """Steps that ended with a fill."""
        self.settled = True
        """The last relaxation ended without a pit (converged, or a step's early stop)."""
        self.name = name or f"harmonic-{engine.backend}"
        self._shape: tuple[int, int] = (0, 0)
        self._goal: Cell = (0, 0)
        self.retries = 0
        """Path reads that needed the tighter tolerance to reach the goal."""
        self.residual = float("inf")
        """The residual the last relaxation ended with."""
        self._cache: tuple[tuple[Cell, int], np.ndarray] | None = None
        self._version = 0
        self._retried = -1
        self._band: tuple[np.ndarray, np.ndarray] | None = None
        self.overlap = engine.backend == "cuda"
        """Start a step's relaxation while the host searches for cells cut off (``_start_early``);
        read at ``plan``."""
        self.overlaps = 0
        """Steps whose relaxation ran beside the host's search and stood."""
        self.undone = 0
        """Steps whose early relaxation the search overruled (cells cut off): undone, run again."""
        self._early: tuple[int, Callable[[], tuple[int, float, bool]],
                           Callable[[], tuple[int, int]] | None] | None = None  # fmt: skip
        self._overlap = False  # ``overlap`` as the last plan found it, where the host searches
        self.fill_behind = True
        """Launch a step's fill right behind its sweeps where the engine can (the CUDA engine's
        ``fill_start``, gated on the device by the sweeps' pit count): one wait a step, not
        one for the sweeps and one for the fill. False: ``fill`` after the sweeps' wait."""

    @property
    def goal(self) -> Cell:
        return self._goal

    @property
    def shape(self) -> tuple[int, int]:
        return self._shape

    def _flat(self, cell: Cell) -> int:
        return (cell[0] + 1) * (self._shape[1] + 2) + cell[1] + 1

    # -- the map ----------------------------------------------------------------------------

    def plan(self, blocked: np.ndarray, goal: Cell) -> UpdateStats:
        t0 = time.perf_counter()
        blocked, shape, goal = checked_plan_input(blocked, goal)
        self._shape, self._goal = shape, goal
        self._band = None
        h, w = shape
        padded = np.ones((h + 2, w + 2), dtype=np.bool_)
        padded[1:-1, 1:-1] = blocked
        flat = padded.reshape(-1)
        g = self._flat(goal)
        self.reach = Reach(flat, g, w + 2)
        steps = self.reach._steps
        if self.init == "distance":
            w0 = np.where(steps >= 0, INIT_SLOPE * steps, rx.BLOCKED_W)
        else:
            w0 = np.where(self.reach.reach, rx.MID_W, rx.BLOCKED_W)
        fixed = ~self.reach.reach
        if not flat[g]:
            w0[g] = 0.0
            fixed[g] = True
        self.engine.load(fixed, w0, w + 2, g)
        # The GPU engine searches the whole map on the device when a change may cut cells off,
        # on maps large enough for that to pay.
        search = getattr(self.engine, "reach_search_start", None)
        self.reach.search = search if flat.size >= DEVICE_SEARCH_CELLS else None
        if search is not None:
            self.reach.warm()  # on any map: the warm-up's is too small to search on the device
        self._overlap = self.overlap and self.reach.search is None
        if self._overlap:
            self.engine.keep_for_undo()
        return self._relax(t0, COLD_SWEEPS)

    def update(self, cells: np.ndarray, blocked: np.ndarray) -> UpdateStats:
        t0 = time.perf_counter()
        cells, values = checked_update_input(self._shape, cells, blocked)
        w = self._shape[1]
        padded = padded_cells(cells, w)
        self._early = None
        early = self._start_early if self._overlap and self.step_sweeps is not None else None
        lost, gained = self.reach.apply(padded, np.ascontiguousarray(values), early)
        if self._early is not None:
            handed, wait, filled = self._early
            if lost.size == handed and gained.size == 0:
                self.overlaps += 1
                return self._step_end(t0, wait, filled)
            wait()  # cells were cut off: the launch read them as free
            self.engine.undo()
            self.undone += 1
        if lost.size == 0 and gained.size == 0:
            return UpdateStats(0, 0, (time.perf_counter() - t0) * 1e3)
        # Cut off or blocked: u = 1, fixed. Newly reachable: no value yet (the next sweep
        # gives it its neighbours' mean; relax_log never over-relaxes from BLOCKED_W).
        self.engine.set(lost, rx.BLOCKED_W, True)
        self.engine.set(gained, rx.BLOCKED_W, False)
        g = self.reach.goal
        if self.reach.reach[g] and (gained == g).any():  # the goal freed again: u = 0
            self.engine.set(np.array([g], dtype=np.int64), 0.0, True)
        return self._relax(t0, WARM_SWEEPS, self.step_sweeps)

    def converge(self) -> UpdateStats:
        """Relax the field to the tolerance (what the replanning steps' early stops left)."""
        return self._relax(time.perf_counter(), WARM_SWEEPS)

    def _relax(self, t0: float, cap: int, budget: int | None = None) -> UpdateStats:
        if budget is not None:
            return self._step(t0, budget)
        sweeps, self.residual, self.settled = self.engine.relax(cap // 4, self.tol, budget)
        if not self.settled:
            # Over-relaxing a log-sum-exp can cycle instead of settling (measured: omega 1.5
            # never converged on the 100² courtyard, 1.3 now and then on a walk's change);
            # Gauss–Seidel (omega 1) always settles, slower: the rest of the budget is its.
            omega = self.engine.omega
            self.engine.omega = type(omega)(1.0)
            more, self.residual, self.settled = self.engine.relax(cap - cap // 4, self.tol, budget)
            self.engine.omega = omega
            sweeps += more
        return self._stats(t0, sweeps)

    def _start_early(self, lost: np.ndarray) -> None:
        """``Reach.apply``'s ``early``: the step's relaxation started on the newly blocked
        cells the goal reached (``lost``) while the host searches the whole map for cells they
        cut off (its cut-off try gave up).

        Exact (the field, sweeps, residual, Idx and fill are the sequential step's, bit for
        bit): ``Reach`` calls this only for a change that frees no cell and leaves the goal
        free, so the step's changes are ``lost`` and the cells cut off C, and no cell gains
        the goal. If the search finds C empty, the launch already running is the step's own:
        ``update`` would queue the same cells with the same value and fixedness (the kernel
        writes each queued cell alike in any order, so the whole-map search's order of the
        same cells is the same launch). If C is not empty, the launch read C's cells as free
        (its residual and pit checks count them), so ``update`` waits for it, ``undo`` copies
        back ``w`` and the fixedness the engine kept just before it (the launch's other
        outputs, Idx, the result words and the pit list, every launch writes afresh), and the
        step runs as before from there. Ordering: the host writes the queue before this launch
        and not again until it has waited for it (``set`` runs after the wait in either case);
        the search reads only the host's arrays; the fill is launched behind the sweeps
        (``_fill_start``; with ``fill_behind`` off, after their wait).

        On the 400² bench walk the steps that search the whole map (26, 34 and 40 at 1/64)
        cut nothing off (their recorded deltas, replayed), and all three start early. H100,
        round 18, interleaved with main in one call: those steps 1.68 / 1.53 / 1.53 and 1.78 /
        1.55 / 1.51 ms against main's 1.98 / 1.65 / 1.67 and 1.85 / 1.61 / 1.24; the host's
        search itself, 0.75–1.2 ms there, is what they cost now."""
        self.engine.set(lost, rx.BLOCKED_W, True)
        wait = self._step_start(int(self.step_sweeps or 0), keep=True)
        # The fill too (``_fill_start``): on a step that leaves pits it runs beside the search.
        self._early = (lost.size, wait, self._fill_start())

    def _step(self, t0: float, budget: int) -> UpdateStats:
        """A replanning step: at most ``step_cap`` sweeps, then the pits' basins filled."""
        wait = self._step_start(budget)
        return self._step_end(t0, wait, self._fill_start())

    def _fill_start(self) -> Callable[[], tuple[int, int]] | None:
        """The step's fill launched behind the sweeps just launched (``fill_behind``, where
        the engine has ``fill_start``): the same field and counts as ``engine.fill`` after
        their wait (``CudaField.fill_start`` states the invariant), without the host's round
        trip between the two (a 20-sweep filling step at 400²: relaxation, wait, fill, wait).
        None: ``_step_end`` fills after the wait."""
        fill_start = getattr(self.engine, "fill_start", None) if self.fill_behind else None
        return fill_start(fl.EPS) if fill_start is not None else None

    def _step_start(self, budget: int, keep: bool = False) -> Callable[[], tuple[int, float, bool]]:
        omega = self.engine.omega
        self.engine.omega = type(omega)(STEP_OMEGA)
        try:
            return self.engine.relax_start(max(self.step_cap, budget), self.tol, budget, keep)
        finally:
            self.engine.omega = omega

    def _step_end(self, t0: float, wait: Callable[[], tuple[int, float, bool]],
                  filled: Callable[[], tuple[int, int]] | None = None) -> UpdateStats:  # fmt: skip
        """``filled``: the answer of a fill already launched behind the sweeps."""
        sweeps, self.residual, _ = wait()
        # Even a step that met ``tol`` fills: the residual skips cells with no value yet.
        self.filled, left = filled() if filled is not None else self.engine.fill(fl.EPS)
        self.fills += int(self.filled > 0)
        self.settled = left == 0
        return self._stats(t0, sweeps)

    def _stats(self, t0: float, sweeps: int) -> UpdateStats:
        self._version += 1
        touched = sweeps * self.reach.count
        return UpdateStats(int(sweeps), int(touched), (time.perf_counter() - t0) * 1e3)

    # -- paths ------------------------------------------------------------------------------

    def _descent(self, start: Cell) -> np.ndarray:
        start = (int(start[0]), int(start[1]))
        if self._shape == (0, 0) or not in_bounds(self._shape, start):
            return _EMPTY
        key = (start, self._version)
        if self._cache is not None and self._cache[0] == key:
            return self._cache[1]
        s = self._flat(start)
        if self.reach.blocked[s]:
            return _EMPTY
        flat = self.engine.descend(s)
        if flat is None and self.reach.reach[s] and self._retried != self._version:
            # A shallow spot the tolerance left: relax further, once per field, then read again.
            self._retried = self._version
            self.retries += 1
            self.engine.relax(RETRY_SWEEPS, self.tol / 10)
            flat = self.engine.descend(s)
        path = _EMPTY if flat is None else _map_cells(flat, self._shape[1] + 2)
        self._cache = (key, path)
        return path

    def path(self, start: Cell) -> np.ndarray:
        return self._descent(start).copy()

    def cost_at(self, cell: Cell) -> int:
        path = self._descent(cell)
        return path_cost(path) if len(path) else int(INF)

    def costs_within(self, r0: int, r1: int, c0: int, c1: int) -> np.ndarray:
        """The cost of each window cell's descent (``int32``, INF where none)."""
        h, w = self._shape
        r0, r1, c0, c1 = max(0, r0), min(h, r1), max(0, c0), min(w, c1)
        out = np.full((max(0, r1 - r0), max(0, c1 - c0)), INF, dtype=np.int32)
        for r in range(r0, r1):
            for c in range(c0, c1):
                out[r - r0, c - c0] = self.cost_at((r, c))
        return out

    def band(self, path: np.ndarray, blocked: np.ndarray) -> np.ndarray:
        """The paper's rubber band of ``path`` in this field (the harmonic planner's smoothing
        model, ``daemon.guidance.smoothing``), ``(k, 2) float64`` in continuous cell units:
        on the GPU, one thread per point (Figure 4), where the field lies on the device.
        ``BAND_ITERATIONS`` a call, from where the last call's band left each path cell."""
        from .rubber_band import band_memory, rubber_band, warm_points

        path = np.asarray(path)
        start = warm_points(path, blocked, self._band)
        if self.backend == "cuda":
            from .band_cuda import rubber_band_cuda

            out = rubber_band_cuda(path, self.engine.w, blocked, pad=1,
                                   iterations=BAND_ITERATIONS, start=start)[0]  # fmt: skip
        else:
            out = rubber_band(path, self.field(), blocked, iterations=BAND_ITERATIONS,
                              start=start)  # fmt: skip
        self._band = band_memory(path, out, blocked.shape[1]) if len(path) > 2 else None
        return out

    def field(self) -> np.ndarray:
        """``w`` of every cell, ``(h, w) float64`` (``rx.BLOCKED_W`` on obstacles and cells the
        goal cannot reach); ``u = 1 − exp(−w)``."""
        h, w = self._shape
        return self.engine.field().reshape(h + 2, w + 2)[1:-1, 1:-1].copy()
