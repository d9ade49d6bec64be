"""EDS steps that need no repair: new obstacles off the user's path wait until something reads.

EDS's contract (``cpu/fast.py``): after every step the path from the user is the reference
Dijkstra's path of the current map, tie for tie, and g along it is exact; the whole field
equals Dijkstra after ``settle()``. Most walking steps need no repair to keep it. The rule:

    Let P be the path this planner returned at its previous step (nothing given to it since
    but reads). If (a) the user's cell s lies on P, (b) every cell of the new delta becomes
    blocked, and (c) no cell of the delta lies on P's suffix from s, then that suffix is the
    step's answer: no repair, no device call, the delta kept pending.

Proof, in the paper's terms. Let g0 be the exact field of the map before the delta and g1
after it. (1) Blocking only removes edges (an edge joins two free cells; diagonals need no
free corners, ``grid.py``), so g1 >= g0 everywhere. (2) No cell of P's suffix is blocked, so
the suffix is still a walk to the goal of cost g0[s]; with (1), g1 = g0 on every cell of it:
g along the path is unchanged and exact, and the suffix is still a shortest path. (3) The
reference path leaves a cell u for the first neighbour n in ``grid.NEIGHBOUR_*`` order with
g[n] + cost(u, n) == g[u]. For u on the suffix, g1[u] = g0[u] <= g0[n] + cost <= g1[n] + cost,
so n satisfies the rule under g1 only if it did under g0: the candidates under g1 are a subset
of those under g0, and P's own next cell is among them (g1 = g0 on it). The first candidate
in the fixed order is therefore the same cell: the suffix is the reference path tie for tie.
The inner planner's queue and stored g are untouched, so nothing it holds becomes wrong; the
map it has is only behind by the pending cells, which reach it once the user has the step's
answer (``between_steps``: the daemon's runner calls it after publishing, the walks after each
step), or merged with the next delta, or before anything reads its field. Given between
steps, they keep P (nothing is pending then) and leave every repair the size of its own delta:
a repair that carried every block deferred since the last one put the H100's p99 at 0.33-0.54
ms at 400² where the plain walk's was 0.14-0.25. A deferred step after a deferred step
applies the same argument to the map that includes the earlier pending blocks: P's suffix
only shrinks as the user walks it, and each delta was checked against the suffix of its step.

Where it applies: maps the device serves (the registry wraps the cuda backend's EDS; the rule
is on when the inner planner's name says ``cuda``). There a repair step is a round trip, ~140
µs on an H100 at 400², and the wrapper adds ~15 µs to it (the check ~9, measured inside the
walk, where the host's caches are cold: the same calls in a loop take 5). On the host a repair
step of such a delta costs 20-30 µs, about what the check does: on the dev VM (2026-11-27,
400², 40 %, two interleaved runs each) the CPU walks took 0.9-1.6 × their time without the
rule, the pending blocks then carried by the next repair. ``defer=True`` applies it anyway
(the CPU property tests do).

Which steps check: every step with a delta after a deferred step (or a plan), none right after
a repair. Repairs come in runs (a wall seen a piece a step: 85-88 % of the steps after a repair
repaired too in the H100's 400² walks, 6-7 % of those after a deferred step), so a step after a
repair repairs at once, and between steps ``misses_suffix`` asks whether the check would have
held for it; if it would, the next step checks again. A skipped check only ever costs a repair
that was not needed, never a wrong path. On the H100 (2026-11-27, old and new interleaved on
one host) this took the wrapper's share of the largest fifth of repairs from 14-34 µs to
8-22, and the 1000² walks' totals up by 0-22 % (the repairs it did not need).

What the wrapper answers itself is what the route asks at every step (``max_open``,
``search_stats``: no ``__getattr__`` miss on the hot path); everything else comes from the
inner planner after the pending blocks are flushed to it.
"""

from __future__ import annotations

import time
from typing import Any

import numpy as np

from .deferred_check import defer_step, misses_suffix
from .grid import Cell
from .interface import GlobalPlanner, UpdateStats

READS = frozenset(
    {"costs", "costs_within", "settle", "pending", "blocked", "device_bytes", "deferred_tiles"}
)
"""Inner attributes that only read (or finish) the field: a lookup flushes and keeps P."""

Step = tuple[UpdateStats, np.ndarray]
_NO_CELLS = np.empty(0, dtype=np.int64)
_NO_VALUES = np.empty(0, dtype=bool)
PENDING_START = 4096
"""Room for pending cells at first (it doubles when a step's delta does not fit)."""


class DeferredBlocks(GlobalPlanner):
    """An EDS planner whose steps return the last path's suffix when the delta misses it."""

    # The route reads both at every step (``getattr(planner, ..., None)``): answered here.
    max_open = None
    search_stats = None
    dss = False

    def __init__(self, inner: GlobalPlanner, defer: bool | None = None) -> None:
        """``defer``: apply the rule (True), or pass every call through (False); None: apply
        it where the inner planner serves the map on the device (its name says ``cuda``),
        decided at each ``plan``, as ``SmallGridsOnCpu`` picks its planner."""
        self.inner = inner
        self._defer = defer
        self.defers = False
        """Whether the rule applies to the current map."""
        self.deferred_steps = 0
        """Steps answered without the inner planner (for tests and the bench's notes)."""
        self.unchecked_steps = 0
        """Steps that repaired without the check (after a repair: see ``deferred``)."""
        self._check = True
        """Whether the next step with a delta runs the check (False after a repair)."""
        self._shared = False
        """Whether other threads' steps met ours on the device lately (``between_steps``)."""
        self._unchecked: tuple[Any, Any, Cell] | None = None
        """The last unchecked step's delta and cell, until ``_mark`` asks whether the check
        would have held (then the next step checks)."""
        # Flat cells blocked but not yet given to inner: the first ``_count`` of ``_pending``
        # (grown as needed), each once (``_is_pending``).
        self._pending = np.empty(PENDING_START, dtype=np.int64)
        self._count = 0
        self._is_pending = np.zeros(0, dtype=bool)
        self._path: np.ndarray | None = None  # P: the last path returned, (k, 2) int32
        self._flat: np.ndarray | None = None  # P's flat indices
        self._at = 0  # the user's index in P at the last step
        self._on = np.zeros(0, dtype=bool)  # per cell: on P's suffix from _at (once marked)
        # A repairing step's own bookkeeping waits for ``between_steps`` (or the next check):
        # the path just returned, not yet marked in ``_on``, and a forgotten P's marks not yet
        # cleared. Marking ~500 cells and clearing as many cost a repair step 10-20 µs.
        self._fresh: np.ndarray | None = None
        self._stale: np.ndarray | None = None
        self._width = 0
        self._cells = 0

    # -- what the interface asks --------------------------------------------------------------

    @property
    def name(self) -> str:  # type: ignore[override]
        return self.inner.name

    @property
    def backend(self) -> str:
        return str(getattr(self.inner, "backend", ""))

    @property
    def variant(self) -> str:
        return str(getattr(self.inner, "variant", ""))

    @property
    def goal(self) -> Cell:
        return self.inner.goal

    @property
    def shape(self) -> tuple[int, int]:
        return self.inner.shape

    def plan(self, blocked: np.ndarray, goal: Cell) -> UpdateStats:
        self._take_pending()  # the plan reads the whole map: what was pending is in it
        self._forget()
        self._check, self._unchecked = True, None
        stats = self.inner.plan(blocked, goal)
        h, w = self.inner.shape
        if self._on.size != h * w:
            self._on = np.zeros(h * w, dtype=bool)
            self._is_pending = np.zeros(h * w, dtype=bool)
            self._stale = None  # marks of the old map's array
        self._width, self._cells = w, h * w
        self.defers = self._defer if self._defer is not None else "-cuda-" in self.inner.name
        if self.defers:
            self.__dict__.pop("update_and_path", None)
            self.__dict__.pop("path", None)
        else:  # the inner planner's own calls, bound here: a step pays no frame of ours
            self.update_and_path = self.inner.update_and_path  # type: ignore[method-assign]
            self.path = self.inner.path  # type: ignore[method-assign]
        return stats

    def update(self, cells: np.ndarray, blocked: np.ndarray) -> UpdateStats:
        cells, values = self.merged(cells, blocked)
        return self.inner.update(cells, values)

    def update_and_path(self, cells: np.ndarray, blocked: np.ndarray, start: Cell) -> Step:
        if self._shared:  # the inner planner's own step, with what was pending (between_steps)
            if self._count:
                cells, blocked = self.merged(cells, blocked)
            return self.inner.update_and_path(cells, blocked, start)
        t0 = time.perf_counter()
        done = self.deferred(cells, blocked, start, t0)
        if done is not None:
            return done
        # merged() and kept() written out for the common case (nothing pending, P forgotten
        # once): inside a walk every frame and attribute a repair step touches is cold.
        if self._count:
            cells, blocked = self.merged(cells, blocked)
        else:
            self._forget()
        stats, path = self.inner.update_and_path(cells, blocked, start)
        if self.defers and len(path):
            self._fresh = path
        ms = (time.perf_counter() - t0) * 1e3  # the check and the merge are the step's too
        return UpdateStats(stats.iterations, stats.cells_touched, max(ms, stats.ms)), path

    def path(self, start: Cell) -> np.ndarray:
        # The rule with an empty delta: from a cell of P's suffix, the suffix is the path
        # (the route reads one at a step that changed nothing, the user a cell further on).
        done = self.deferred(_NO_CELLS, _NO_VALUES, start)
        if done is not None:
            return done[1]
        if self._count:  # one step of the inner planner, not an update and then a read
            cells, values = self.merged(_NO_CELLS, _NO_VALUES)
            path = self.inner.update_and_path(cells, values, start)[1]
        else:
            self._forget()
            path = self.inner.path(start)
        self.kept(path)  # the reference path from ``start``: the next step may keep it
        return path

    def cost_at(self, cell: Cell) -> int:
        self.flush()
        return self.inner.cost_at(cell)

    def __getattr__(self, attr: str) -> Any:
        # What only some inner planners offer (costs, costs_within, settle, pending, blocked,
        # the cuda planner's statistics, parts): from the inner planner, once it holds the
        # current map. A name that is not a known read may change the inner planner: P is
        # forgotten, so the next step repairs.
        if attr.startswith("_") or "inner" not in self.__dict__:
            raise AttributeError(attr)
        self.flush()
        if attr not in READS:
            self._forget()
        value = getattr(self.__dict__["inner"], attr)
        if attr == "parts":  # the warm-up's: each part behind the rule, so its check runs too
            return lambda: [DeferredBlocks(part, defer=True) for part in value()]
        return value

    # -- the rule -----------------------------------------------------------------------------

    def deferred(
        self, cells: np.ndarray, blocked: np.ndarray, start: Cell, t0: float | None = None
    ) -> Step | None:
        """The step's answer when it needs no repair (the rule above; the delta is then
        pending), else None: nothing pending changed, and the caller repairs (P forgotten)."""
        t0 = time.perf_counter() if t0 is None else t0
        if self._fresh is not None or self._stale is not None:
            self._mark()
        if not self._check and len(cells):
            # The last step repaired: this one most likely does too (85-88 % of the steps
            # after a repair in the 400² walks, 6-7 % after a deferred one), so it repairs
            # without paying the check (9-20 µs of a repair step's time on a GPU host).
            # ``_mark`` asks afterwards, between steps, whether it would have held.
            self._unchecked = (cells, blocked, start)
            self.unchecked_steps += 1
            return None
        flat = self._flat
        if flat is None:  # no P (or the rule is off: kept() keeps none)
            return None
        r, c = int(start[0]), int(start[1])
        if not (0 <= c < self._width and 0 <= r * self._width < self._cells):
            return None
        try:
            if self._count + len(cells) > self._pending.size:  # room for the delta's cells
                grown = np.empty(2 * (self._count + len(cells)), dtype=np.int64)
                grown[: self._count] = self._pending[: self._count]
                self._pending = grown
            at, self._count = defer_step(
                flat, self._at, r * self._width + c, self._on, cells, blocked,
                self._is_pending, self._pending, self._count,
            )  # fmt: skip
        except TypeError:  # not the route's form, the only one compiled: made so
            at = -2
        if at == -2:  # (or one value for every cell)
            cells = np.array(cells, dtype=np.int64).reshape(-1)
            values = np.asarray(blocked, dtype=np.bool_)
            if values.size == cells.size:
                values = values.reshape(-1)
            blocked = np.array(np.broadcast_to(values, cells.shape))
            return self.deferred(cells, blocked, start, t0)
        if at < 0:
            if len(cells):  # (a path read's failure says nothing of the steps' deltas)
                self._check = False
            return None
        self._at = at
        self.deferred_steps += 1
        assert self._path is not None
        return UpdateStats(0, 0, (time.perf_counter() - t0) * 1e3), self._path[at:].copy()

    def merged(self, cells: np.ndarray, blocked: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The pending blocks and the new delta as one delta for the inner planner (pending
        cleared, P forgotten until ``kept``). The new delta's value wins for a cell in both:
        a pending block that it frees again is dropped, and its free reaches the inner
        planner, which still has the cell free (its own no-op change) unless the block was a
        no-op itself, when the free is the change it must see."""
        self._forget()
        if not self._count:
            return cells, blocked
        cells = np.asarray(cells, dtype=np.int64).reshape(-1)
        if cells.size and (int(cells.min()) < 0 or int(cells.max()) >= self._cells):
            # the inner planner would refuse the merged delta whole: the pending blocks stay
            raise IndexError(f"a cell index is outside the {self.shape} map")
        values = np.broadcast_to(np.asarray(blocked, dtype=bool), cells.shape)
        if cells.size:  # masks, not sorts: thousands of pending cells cost ~0.5 ms sorted
            self._is_pending[cells] = False
        pend = self._take_pending()
        merged = np.concatenate([pend, cells])
        return merged, np.concatenate([np.ones(pend.size, dtype=bool), values])

    def kept(self, path: np.ndarray) -> None:
        """Remember ``path``, just returned by the inner planner's step, as P (marked in
        ``_on`` by ``_mark``, once the step's answer is out)."""
        self._forget()
        if len(path) and self._width and self.defers:
            self._fresh = path

    def between_steps(self) -> None:
        """The step's answer is out: the blocks it deferred go to the inner planner now, so
        the next repair carries only its own delta. P stays the path: with nothing pending
        the inner planner's field is the current map's, and P crossed none of them. Given as
        a step from the user's cell (``pending_step``): on the device it is posted with the
        steps other users' threads call meanwhile (``cuda/combine.py``), not alone.

        While the device is shared (``shared_now``: other threads' steps met ours lately)
        they ride with the next step, and every step is the inner planner's own, P forgotten:
        the host, not the device, then limits the steps a second, and the rule's check and
        marks are host work the threads share one interpreter for (1,000 users at 10 Hz, a
        thread each, an H100 host: 7,332 steps/s with them, 9,440 without the rule; in this
        form, interleaved on one host: 7,036-7,300 against 7,887-8,161). Once the device is no
        longer shared, the next repair's path is P again."""
        shared = getattr(self.inner, "shared_now", None)
        self._shared = shared is not None and bool(shared())
        if self._shared:  # no P to mark: it would only be cleared again
            self._forget()
            return
        self._mark()  # the last step's P, marked now rather than in the next step
        if not self._count:
            return
        step = self.pending_step()
        if step is not None:
            inner, cells, blocked, start = step
            inner.update_and_path(cells, blocked, start)
        else:
            self.flush()

    def pending_step(self) -> tuple[GlobalPlanner, np.ndarray, np.ndarray, Cell] | None:
        """The pending blocks, taken, as a step of the inner planner from the user's cell on
        P, for a caller that posts it (with others': ``cuda/batch.between_steps_many``); its
        path is P's suffix from there (the rule's proof). None when nothing is pending or
        there is no P. A caller whose step fails must have the planner plan afresh, as the
        route does (the blocks are no longer pending)."""
        self._mark()
        if not self._count or self._flat is None:
            return None
        cells = self._take_pending()
        r, c = divmod(int(self._flat[self._at]), self._width)
        return self.inner, cells, np.ones(cells.size, dtype=bool), (r, c)

    def flush(self) -> None:
        """Give the pending blocks to the inner planner (before anything reads its field)."""
        if self._count:
            pend = self._take_pending()
            self.inner.update(pend, np.ones(pend.size, dtype=bool))

    def pending_blocks(self) -> int:
        """Cells blocked by deferred steps and not yet given to the inner planner."""
        return self._count

    def _take_pending(self) -> np.ndarray:
        """The pending cells still marked (a new delta unmarks those it sets), cleared."""
        if not self._count:
            return _NO_CELLS
        pend = self._pending[: self._count]
        pend = pend[self._is_pending[pend]]
        self._is_pending[pend] = False
        self._count = 0
        return pend

    def _forget(self) -> None:
        """No P: its marks are cleared by ``_mark`` (a step's reads of ``_on`` all follow it)."""
        self._fresh = None
        if self._flat is not None:
            if self._stale is not None:
                self._on[self._stale] = False
            self._stale = self._flat[self._at :]
        self._path = self._flat = None
        self._at = 0

    def _mark(self) -> None:
        """Bring ``_on`` up to date: a forgotten P's suffix cleared, a kept path marked as P.
        First, after an unchecked step, whether its delta missed that suffix: if so the next
        step checks (it most likely defers), else it repairs unchecked too."""
        if self._unchecked is not None:
            cells, blocked, start = self._unchecked
            self._unchecked = None
            self._check = self._stale is None or self._missed(self._stale, cells, blocked, start)
        if self._stale is not None:
            self._on[self._stale] = False
            self._stale = None
        path = self._fresh
        if path is not None:
            self._fresh = None
            flat = path[:, 0].astype(np.int64) * self._width + path[:, 1]
            self._on[flat] = True
            self._path, self._flat, self._at = path, flat, 0

    def _missed(self, suffix: np.ndarray, cells: Any, blocked: Any, start: Cell) -> bool:
        """``misses_suffix`` for a delta of any form (True where the compiled form does not
        fit: the next step then checks; either answer is safe, a wrong one costs a repair)."""
        s = int(start[0]) * self._width + int(start[1])
        try:
            return bool(misses_suffix(suffix, s, self._on, cells, blocked))
        except TypeError:  # not the route's form
            return True
