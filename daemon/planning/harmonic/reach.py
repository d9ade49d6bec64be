"""Which free cells the goal reaches, kept up to date on the host for either engine.

The relaxation must hold every cell the goal cannot reach at ``u`` = 1 (``w`` = BLOCKED_W):
a pocket left free drifts towards 1 for ever, and its residual never falls below the
tolerance. Recomputing reachability (an 8-connected BFS, O(n)) at every change costs 10 ms
and more at 2000², the whole step's budget, so a change is checked where it happened:

- A blocked cell can cut a region off only if the free cells around the newly blocked ones
  no longer connect to one another. If, for each 8-connected cluster of the newly blocked
  cells, those around it still join up inside a window round the cluster (its bounding box
  widened by ``MARGIN``), every path the change crossed can be rerouted round it and nothing
  was cut off (splice the old path at its first and last contact with each cluster).
  Otherwise the cells cut off are found from where the change happened (``cut_off``), and
  only past a budget by one search of the whole map (``floods.reached_runs``, or the
  device's).
- A freed cell joins the reachable set when it touches it, and brings with it the pocket it
  opens: a BFS from there through cells not reached yet.
"""

from __future__ import annotations

from collections.abc import Callable

import numba
import numpy as np

from .clusters import _joined_each
from .cut_off import cut_off, neighbour_offsets
from .floods import flood, free_runs, reached_runs
from .relax import bfs_steps

MARGIN = 16
"""Cells the connectivity window extends past the change's bounding box."""
CUT_SHARE = 8
"""``cut_off`` gives up (the whole-map search follows) past 1/CUT_SHARE of the map where
``Reach.search`` (the device's) is at hand, ..."""
HOST_CUT_SHARE = 64
"""... and past 1/HOST_CUT_SHARE where the whole-map search is the host's
(``floods.reached_runs``: ~0.07–0.10 ms on the 400² bench walk's map, ~800 free runs, dev
VM; it was a scanline fill, ~0.4–0.7), as a try costs ~47 ns a cell it searches. Tried at
1/256 on the walk's 59 recorded deltas (dev VM, CPU time, min of 7, load 3–4): the three
that need the whole-map search (26, 34, 40) 0.16–0.18 → 0.14–0.15 ms, no delta slower; at
1/1024 the tries of 42, 53 and 54 (which find cells cut off) give up too, 0.05–0.07 →
0.10–0.11 ms. Kept at 1/64: at 1/256 a ring round a pocket of 15² on a 300² map, or 39² on
1024², no longer ends in the try, and the whole-map search grows with the map where the try
grows with the pocket. At 1/8, with the scanline fill, the one step whose try fails paid the
try and the search together (H100, the bench's walk: step 26 1.95 ms, 1.51 at 1/64)."""
SCRATCH_SHARE = 8
"""``Reach``'s lists are written at construction as far as a large step reaches, 1/8 of the
map (the 2000² walk's first sweep and reveal: 119 514 and 137 243 of 4 M cells)."""
CUT_CELLS_BESIDE_SEARCH = 1 << 16
"""... and past this many cells where ``Reach.search`` (the device's whole-map search, ~1 ms)
is at hand: a host search that runs on into 1/8 of a 2000² map costs more than it."""
FIRST_TRY_SHARE = 16
"""Beside ``Reach.search``, ``cut_off`` first tries 1/FIRST_TRY_SHARE of its budget; past
that the device's search is started, and the try goes on to its whole budget while the
device works (the 2000² bench walk's reveal: a try that fails, then the device's search)."""


@numba.njit(cache=True, nogil=True)
def padded_cells(cells, width):
    """Cells ``r · width + c`` of a map ``width`` wide as cells of its padded map, ``(r + 1) ·
    (width + 2) + c + 1``, in one pass: the row by a floating-point product, corrected by
    one, not an integer division (numpy's division and two temporaries took 0.43 ms of the
    2000² walk's first sweep, 119 514 cells, dev VM)."""
    out = np.empty(cells.size, dtype=np.int64)
    inv = 1.0 / width
    for k in range(cells.size):
        c = cells[k]
        r = np.int64(c * inv)
        r += (r + 1) * width <= c
        r -= r * width > c
        out[k] = c + 2 * r + width + 3
    return out


@numba.njit(cache=True, nogil=True)
def _grow(blocked, reach, freed, width, queue, out) -> int:
    """Cells newly reached through the freed cells; written to ``out``, count returned."""
    around = neighbour_offsets(width)
    tail = 0
    for i in freed:
        if blocked[i] or reach[i]:
            continue
        for o in around:
            j = i + o
            if reach[j] and not blocked[j]:
                reach[i] = True
                queue[tail] = i
                tail += 1
                break
    tail = flood(blocked, reach, width, queue, 0, tail)
    out[:tail] = queue[:tail]
    return tail


@numba.njit(cache=True, nogil=True)
def _flips(blocked, reach, cells, values, mark, out, was) -> tuple[int, int]:
    """Apply a delta to ``blocked``, a cell named twice taking its last value (the map's own
    rule). The cells whose value flipped: the newly blocked at the front of ``out`` (their
    old reach in ``was``, then cleared in ``reach``), the freed at its back; returns the two
    counts. One pass over the delta, not a sort (``np.unique`` took ~0.2 ms of a 400² step)
    nor numpy's indexing of the flips once per use (~2 ms of the 2000² first sweep's 119 k
    cells). ``mark``: scratch of zeros, left zeroed; only a delta not strictly increasing
    needs it (the navigator's flipped cells are, so no cell is named twice): its two passes
    of scattered writes were ~0.4 of this function's time on the 2000² first sweep."""
    ordered = True
    for k in range(1, cells.size):
        if cells[k] <= cells[k - 1]:
            ordered = False
            break
    nb = nf = 0
    for k in range(cells.size - 1, -1, -1):
        c = cells[k]
        if not ordered:
            if mark[c]:
                continue
            mark[c] = 1
        if blocked[c] == values[k]:
            continue
        blocked[c] = values[k]
        if values[k]:
            out[nb] = c
            was[nb] = reach[c]
            reach[c] = False
            nb += 1
        else:
            nf += 1
            out[out.size - nf] = c
    if not ordered:
        for k in range(cells.size):
            mark[cells[k]] = 0
    return nb, nf


@numba.njit(cache=True, nogil=True)
def _answered(reach, changed, now_blocked, was, lost, gained) -> tuple[int, int]:
    """The whole-map search's answer (``changed``: the cells whose reach differs from the
    reach before the change) applied to ``reach``, which holds the reach after ``_flips``
    (``now_blocked`` cleared; their old reach ``was``): the cells lost and gained, in
    ``changed``'s order, into ``lost`` and ``gained``; returns the two counts. One pass, not
    numpy's six scatters and gathers of up to ~137 k cells on the 2000² walk's reveal."""
    for k in range(now_blocked.size):
        reach[now_blocked[k]] = was[k]
    n_lost = n_gained = 0
    for c in changed:
        if reach[c]:
            reach[c] = False
            lost[n_lost] = c
            n_lost += 1
        else:
            reach[c] = True
            gained[n_gained] = c
            n_gained += 1
    return n_lost, n_gained


class Reach:
    """The padded map, its goal and the reached mask (``reach``: bool, padded flat)."""

    def __init__(self, blocked: np.ndarray, goal: int, width: int) -> None:
        self.blocked = blocked.copy()
        self.goal, self.width = int(goal), int(width)
        self.height = blocked.size // width
        self.reach = np.zeros(blocked.size, dtype=np.bool_)
        self._steps = np.empty(blocked.size, dtype=np.int64)
        self._queue = np.empty(blocked.size, dtype=np.int64)
        self._mark = np.zeros(blocked.size, dtype=np.int8)
        self._label = np.zeros(blocked.size, dtype=np.int8)
        self._group = np.zeros(blocked.size, dtype=np.int32)
        self._failed = np.empty(blocked.size, dtype=np.int64)
        self._out = np.empty(blocked.size, dtype=np.int64)
        self._flips = np.empty(blocked.size, dtype=np.int64)
        # Only the newly blocked cells' old reach is kept (a whole copy costs ~1 ms at 2000²).
        self._was = np.empty(blocked.size, dtype=np.bool_)
        # Written now, so the kernel maps their pages at plan, not in a step (np.zeros and
        # np.empty leave each 4 KiB page to a fault on its first write): the scratch indexed
        # by cell whole, as a sweep's changes spread over the map write it nearly everywhere;
        # the lists only as far as a large step reaches (1/SCRATCH_SHARE of the map: the
        # cut-off budget beside a device search; a sweep's delta), 4 MB each at 2000² where
        # whole they would hold ~130 MB more a user. The 2000² walk's first sweep and
        # reveal, replayed (dev VM): 818–896 and 313–339 minor faults -> 0 and 0 (~3 µs of
        # CPU each there).
        for scratch in (self._mark, self._label, self._group):
            scratch.fill(0)
        front = blocked.size // SCRATCH_SHARE
        for scratch in (self._queue, self._failed, self._out, self._flips):
            scratch[:front] = 0
        self._was[:front] = False
        # The host's whole-map search's scratch, by runs (int32: a map of under 2**31 cells):
        # twice the runs of the map as first given, grown when a change leaves more.
        self._runs = np.empty((4, 0), dtype=np.int32)
        self._more_runs(2 * free_runs(self.blocked, self._runs[0], self._runs[1]))
        self.full_searches = 0
        """Changes that needed the whole-map BFS."""
        self.search: Callable[[np.ndarray, np.ndarray, int], Callable[[], np.ndarray]] | None = None
        """The whole-map search elsewhere (the GPU engine's ``reach_search_start``): given the
        map, the reach before the change and the goal (both read before it returns), it
        starts the search and returns what waits for its answer, the cells whose reach
        changed (in any order); None: the host's (``floods.reached_runs``)."""
        self.cut_searches = 0
        """Changes whose cut-off cells ``cut_off`` found without it."""
        bfs_steps(self.blocked, self.goal, self.width, self._steps)
        """8-connected steps from the goal of the map as first given (a plan's first guess);
        not kept up by ``apply``."""
        self.reach[:] = self._steps >= 0
        self.count = int(self.reach.sum())
        """Cells reached; kept up by ``apply`` (a sum over 4 M cells is ~1 ms at 2000²)."""

    def _more_runs(self, count: int) -> None:
        """Scratch for ``count`` runs (at least 1024: a few KiB)."""
        cap = max(count, 1024)
        self._runs = np.zeros((4, cap), dtype=np.int32)
        self._run_flags = np.zeros(cap, dtype=np.int8)
        self._run_stack = np.zeros(cap, dtype=np.int32)

    def warm(self) -> None:
        """Compile ``_answered`` and the host's whole-map search (or load them from numba's
        cache) now: only a ``search``'s answer runs the one, only a try that gives up the
        other, so a walk's first such step paid it (H100, the 2000² bench walk's reveal: 223
        ms with ``_answered``'s compile)."""
        none = np.empty(0, dtype=np.int64)
        _answered(self.reach, none, none, self._was[:0], self._out, self._failed)
        tiny = np.ones(9, dtype=np.bool_)  # one free cell, the goal, inside its border
        tiny[4] = False
        reached_runs(tiny, 4, 3, np.zeros(9, dtype=np.bool_), none, True, self._runs,
                     self._run_flags, self._run_stack, self._out, self._failed)  # fmt: skip

    def _start(self, now_blocked: np.ndarray, was: np.ndarray) -> Callable[[], np.ndarray]:
        """``search`` started on the reach before the change; ``reach`` is left as it was."""
        assert self.search is not None
        self.reach[now_blocked] = was
        wait = self.search(self.blocked, self.reach, self.goal)
        self.reach[now_blocked] = False
        return wait

    def _afresh(
        self,
        now_blocked: np.ndarray,
        was: np.ndarray,
        split_only: bool,
        wait: Callable[[], np.ndarray] | None = None,
    ) -> tuple[np.ndarray, np.ndarray]:
        """Every reached cell found afresh (a change may have cut some off): ``(lost,
        gained)`` against the reach before the change (``now_blocked``'s old reach ``was``);
        ``split_only``: the change freed no cell (the host's search then reads one cell a run
        for its old reach); ``wait``: the answer of a ``search`` already started."""
        self.full_searches += 1
        if self.search is not None:
            if wait is None:
                wait = self._start(now_blocked, was)
            n_lost, n_gained = _answered(self.reach, wait(), now_blocked, was, self._out,
                                         self._failed)  # fmt: skip
            self.count += n_gained - n_lost
            return self._out[:n_lost].copy(), self._failed[:n_gained].copy()
        was_lost = np.sort(now_blocked[was])
        while True:
            count, n_lost, n_gained = reached_runs(
                self.blocked, self.goal, self.width, self.reach, was_lost, split_only,
                self._runs, self._run_flags, self._run_stack, self._out, self._failed,
            )  # fmt: skip
            if count >= 0:
                break
            self._more_runs(-2 * count)
        self.count = count
        return self._out[:n_lost].copy(), self._failed[:n_gained].copy()

    def _cut_off(self, seeds: int, limit: int) -> int:
        return cut_off(self.blocked, self.reach, self._failed[:seeds], self.width, self.goal,
                       self._group, self._queue, self._out, limit)  # fmt: skip

    def apply(
        self,
        cells: np.ndarray,
        values: np.ndarray,
        early: Callable[[np.ndarray], None] | None = None,
    ) -> tuple[np.ndarray, np.ndarray]:
        """Set ``blocked[cells] = values``; returns ``(lost, gained)``: padded flat cells whose
        reachability changed (newly blocked cells count as lost; newly freed ones that the goal
        reaches as gained). ``early``: called with the newly blocked cells the goal reached
        before the host's whole-map search starts (the cut-off try gave up), when the change
        frees none and leaves the goal free: then ``lost`` is those cells and the cells cut
        off, ``gained`` empty (the planner starts the relaxation on them meanwhile). Not before
        the try: on the 400² bench walk's recorded deltas the three tries that end (42, 53,
        54) each find cells cut off (12, 201, 4), where a relaxation started early is undone,
        and the three whole-map searches (26, 34, 40) none."""
        flips = self._flips
        nb, nf = _flips(self.blocked, self.reach, cells, values, self._label, flips,
                        self._was)  # fmt: skip
        if nb + nf == 0:
            return flips[:0], flips[:0]
        now_blocked, freed, was = flips[:nb], flips[flips.size - nf :], self._was[:nb]
        if not self.blocked[self.goal] and not self.reach[self.goal]:
            return self._afresh(now_blocked, was, nf == 0)  # the goal itself freed
        cut = 0
        seeds = 0  # the contacts of the clusters that failed, listed in self._failed
        if nb and not self.blocked[self.goal]:
            seeds = _joined_each(self.blocked, self.reach, now_blocked, self.width, self.height,
                                  MARGIN, self._mark, self._queue, self._label,
                                  self._failed, self._out)  # fmt: skip
        if nb and (self.blocked[self.goal] or seeds):
            wait = None
            if not self.blocked[self.goal]:
                share = CUT_SHARE if self.search is not None else HOST_CUT_SHARE
                limit = self.blocked.size // share
                if self.search is not None:
                    # A short try first; if it gives up, the device's search starts, and the
                    # try goes on to the whole budget meanwhile (each try is the same search,
                    # so it ends as the one try with the whole budget would: the same cuts).
                    limit = min(limit, CUT_CELLS_BESIDE_SEARCH)
                    cut = self._cut_off(seeds, limit // FIRST_TRY_SHARE)
                    if cut < 0:
                        wait = self._start(now_blocked, was)
                        cut = self._cut_off(seeds, limit)
                else:
                    cut = self._cut_off(seeds, limit)
            if self.blocked[self.goal] or cut < 0:
                if early is not None and nf == 0 and self.search is None and wait is None:
                    early(now_blocked[was])
                return self._afresh(now_blocked, was, nf == 0, wait)
            self.cut_searches += 1
        lost = now_blocked[was]
        if cut:
            lost = np.concatenate((lost, self._out[:cut]))
        gained = self._out[: _grow(self.blocked, self.reach, freed, self.width, self._queue,
                                   self._out)]  # fmt: skip
        self.count += gained.size - lost.size
        return lost, gained.copy()
