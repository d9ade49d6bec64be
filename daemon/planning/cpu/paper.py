"""The paper's Figure 4 on the CPU: EDS and DSS as whole-grid synchronous iterations.

Díaz-Toro et al. 2022 keep three maps per cell — ``g`` (cost to the goal), ``pred`` (the
neighbour g came from) and ``incon`` (g may be wrong) — each as a read-only map (``*_r``)
and a write-only map (``*_w``). One iteration computes every cell of the write-only maps
from the read-only ones only, so all cells could run at once (one GPU thread each); at the
end of the iteration the buffers swap. Iterations repeat until ``flag_stop``: an iteration
in which no cell changed. Here each iteration is a handful of numpy operations over the
block of rows and columns that holds inconsistent cells (cells outside it cannot change).

- **DSS**: g = INF everywhere, the goal inconsistent; relax until flag_stop.
- **EDS**: *set inconsistencies* — newly blocked cells get g = INF; *propagate* — a cell whose
  pred now has g = INF gets g = INF too, iteration after iteration, down the pred tree;
  then the raised cells and the newly freed cells are inconsistent and the relaxation
  iterates until flag_stop.

``UpdateStats.iterations`` counts whole-grid iterations (propagation and relaxation, the
final one that finds nothing to change included), comparable with the paper's Iter_avg.
``cells_touched`` sums the inconsistent cells evaluated over all iterations.
The path follows g by the fixed neighbour order (``dijkstra.reference_path``'s rule), the
same cells on every backend; ``pred`` is what the propagation step walks.
"""

from __future__ import annotations

import time

import numpy as np

from ..field import FieldPlanner
from ..grid import (
    INF,
    NEIGHBOUR_COST,
    NEIGHBOUR_DC,
    NEIGHBOUR_DR,
    NO_PRED,
    Cell,
    in_bounds,
)  # fmt: skip
from ..interface import UpdateStats
from . import dial


class PaperCpuPlanner(FieldPlanner):
    backend, variant = "cpu", "paper"

    def __init__(self, dss: bool = False) -> None:
        super().__init__(dss)
        self._shape: tuple[int, int] = (0, 0)
        self._goal: Cell = (0, 0)

    # -- maps (padded by one blocked ring so every cell has eight neighbours) ------------

    def _allocate(self, shape: tuple[int, int]) -> None:
        h, w = shape
        self._shape = shape
        self.blocked_map = np.ones((h + 2, w + 2), dtype=bool)
        self.g_r = np.full((h + 2, w + 2), INF, dtype=np.int32)
        self.g_w = self.g_r.copy()
        self.pred_r = np.full((h + 2, w + 2), NO_PRED, dtype=np.int8)
        self.pred_w = self.pred_r.copy()
        self.incon_r = np.zeros((h + 2, w + 2), dtype=bool)
        self.incon_w = self.incon_r.copy()
        self.raised_total = self.incon_r.copy()

    def _swap(self) -> None:
        self.g_r, self.g_w = self.g_w, self.g_r
        self.pred_r, self.pred_w = self.pred_w, self.pred_r
        self.incon_r, self.incon_w = self.incon_w, self.incon_r

    def _active_block(self) -> tuple[slice, slice] | None:
        """Rows and columns (padded coordinates) spanning every inconsistent cell."""
        rows = np.flatnonzero(self.incon_r.any(axis=1))
        if rows.size == 0:
            return None
        cols = np.flatnonzero(self.incon_r[rows[0] : rows[-1] + 1].any(axis=0))
        return slice(rows[0], rows[-1] + 1), slice(cols[0], cols[-1] + 1)

    def _begin_iteration(self) -> tuple[slice, slice] | None:
        """Start an iteration of Figure 4: the write maps begin as copies of the read maps.
        Returns the block spanning the inconsistent cells, or None (nothing is inconsistent,
        and incon_w is cleared)."""
        self.g_w[...] = self.g_r
        self.pred_w[...] = self.pred_r
        block = self._active_block()
        if block is None:
            self.incon_w[...] = False
        return block

    @staticmethod
    def _neighbour(a: np.ndarray, block: tuple[slice, slice], k: int) -> np.ndarray:
        """View of ``a`` shifted so that element i is cell i's k-th neighbour."""
        rs, cs = block
        dr, dc = int(NEIGHBOUR_DR[k]), int(NEIGHBOUR_DC[k])
        return a[rs.start + dr : rs.stop + dr, cs.start + dc : cs.stop + dc]

    def _mark_neighbours_incon(self, changed: np.ndarray, block: tuple[slice, slice]) -> None:
        """incon_w := the eight neighbours of every changed cell (their g may now be wrong)."""
        self.incon_w[...] = False
        for k in range(8):
            rs, cs = block
            dr, dc = int(NEIGHBOUR_DR[k]), int(NEIGHBOUR_DC[k])
            view = self.incon_w[rs.start - dr : rs.stop - dr, cs.start - dc : cs.stop - dc]
            view |= changed
        self.incon_w[0, :] = self.incon_w[-1, :] = False  # the padding ring never changes
        self.incon_w[:, 0] = self.incon_w[:, -1] = False

    # -- Figure 4: one iteration of each kind ----------------------------------------------

    def _propagate_iteration(self) -> tuple[bool, int]:
        """Inconsistent cells whose pred has g = INF get g = INF. Returns (flag_stop, evaluated)."""
        block = self._begin_iteration()
        if block is None:
            return True, 0
        incon, g, pred = self.incon_r[block], self.g_r[block], self.pred_r[block]
        pred_g = np.full(g.shape, INF, dtype=np.int32)
        for k in range(8):
            sel = pred == k
            pred_g[sel] = self._neighbour(self.g_r, block, k)[sel]
        raised = incon & (g < INF) & (pred != NO_PRED) & (pred_g >= INF)
        self.g_w[block][raised] = INF
        self.pred_w[block][raised] = NO_PRED
        self._mark_neighbours_incon(raised, block)
        self.raised_total[block] |= raised
        return not raised.any(), int(np.count_nonzero(incon))

    def _relax_iteration(self) -> tuple[bool, int]:
        """Inconsistent cells take the best neighbour's g + cost. Returns (flag_stop, evaluated)."""
        block = self._begin_iteration()
        if block is None:
            return True, 0
        incon, g = self.incon_r[block], self.g_r[block]
        best = np.full(g.shape, INF, dtype=np.int32)
        best_k = np.full(g.shape, NO_PRED, dtype=np.int8)
        for k in range(8):
            through = self._neighbour(self.g_r, block, k) + NEIGHBOUR_COST[k]
            better = through < best  # strict: the first neighbour in the order wins a tie
            best[better] = through[better]
            best_k[better] = k
        rs, cs = block
        gr, gc = self._goal[0] + 1, self._goal[1] + 1
        if rs.start <= gr < rs.stop and cs.start <= gc < cs.stop:
            best[gr - rs.start, gc - cs.start] = 0
            best_k[gr - rs.start, gc - cs.start] = NO_PRED
        blocked = self.blocked_map[block]
        best[blocked] = INF
        best_k[blocked] = NO_PRED
        changed = incon & (best != g)
        self.g_w[block][changed] = best[changed]
        self.pred_w[block][changed] = best_k[changed]
        self._mark_neighbours_incon(changed, block)
        return not changed.any(), int(np.count_nonzero(incon))

    def _iterate(self, step) -> tuple[int, int]:
        """Run ``step`` until flag_stop, swapping buffers after each iteration."""
        iterations = evaluated = 0
        while True:
            flag_stop, n = step()
            self._swap()
            iterations += 1
            evaluated += n
            if flag_stop:
                return iterations, evaluated

    # -- DSS and EDS ---------------------------------------------------------------------

    def plan(self, blocked: np.ndarray, goal: Cell) -> UpdateStats:
        t0 = time.perf_counter()
        self.blocked_map[1:-1, 1:-1] = self._take_plan(blocked, goal)
        return self._dss(t0)

    def _dss(self, t0: float) -> UpdateStats:
        self.g_r[...] = INF
        self.pred_r[...] = NO_PRED
        self.incon_r[...] = False
        self.incon_r[self._goal[0] + 1, self._goal[1] + 1] = True
        iterations, evaluated = self._iterate(self._relax_iteration)
        return UpdateStats(iterations, evaluated, (time.perf_counter() - t0) * 1e3)

    def _apply(self, cells: np.ndarray, blocked: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Set the blocked map; return the padded (rows, cols) of the cells in the change."""
        self._require_plan()
        h, w = self._shape
        cells = np.asarray(cells, dtype=np.int64).ravel()
        values = np.broadcast_to(np.asarray(blocked, dtype=bool).ravel(), cells.shape)
        if cells.size and (cells.min() < 0 or cells.max() >= h * w):
            raise IndexError(f"a cell index is outside the {h}x{w} map")
        rows, cols = cells // w + 1, cells % w + 1
        self.blocked_map[rows, cols] = values
        return rows, cols

    def _repair(self, cells: np.ndarray, blocked: np.ndarray) -> UpdateStats:
        t0 = time.perf_counter()
        rows, cols = self._apply(cells, blocked)
        # Set inconsistencies (every iteration starts by copying the read-only maps into the
        # write-only ones, so editing the read-only maps here is enough).
        now_blocked = self.blocked_map[rows, cols]
        raise_r, raise_c = rows[now_blocked], cols[now_blocked]
        had_cost = self.g_r[raise_r, raise_c] < INF
        raise_r, raise_c = raise_r[had_cost], raise_c[had_cost]
        free_r, free_c = rows[~now_blocked], cols[~now_blocked]
        was_blocked = self.g_r[free_r, free_c] >= INF  # blocked cells always hold INF
        free_r, free_c = free_r[was_blocked], free_c[was_blocked]
        self.raised_total[...] = False
        self.g_r[raise_r, raise_c] = INF
        self.pred_r[raise_r, raise_c] = NO_PRED
        self.raised_total[raise_r, raise_c] = True
        # Propagate the inconsistency down the pred tree.
        self.incon_r[...] = False
        for k in range(8):
            self.incon_r[raise_r - NEIGHBOUR_DR[k], raise_c - NEIGHBOUR_DC[k]] = True
        self.incon_r[self.blocked_map] = False
        it_raise, ev_raise = self._iterate(self._propagate_iteration)
        # Relax: every raised cell and every freed cell is inconsistent.
        self.incon_r[...] = self.raised_total & ~self.blocked_map
        self.incon_r[free_r, free_c] = True
        it_relax, ev_relax = self._iterate(self._relax_iteration)
        ms = (time.perf_counter() - t0) * 1e3
        return UpdateStats(it_raise + it_relax, ev_raise + ev_relax, ms)

    def _recompute(self, cells: np.ndarray, blocked: np.ndarray) -> UpdateStats:
        t0 = time.perf_counter()
        self._apply(cells, blocked)
        return self._dss(t0)

    def _require_plan(self) -> None:
        if self._shape == (0, 0):
            raise RuntimeError("call plan(blocked, goal) before update")

    # -- queries --------------------------------------------------------------------------

    def costs(self) -> np.ndarray:
        return self.g_r[1:-1, 1:-1].copy()

    def blocked(self) -> np.ndarray:
        return self.blocked_map[1:-1, 1:-1].copy()

    def pred(self) -> np.ndarray:
        """The pred map (``int8`` neighbour index, -1 for goal, blocked, unreachable)."""
        return self.pred_r[1:-1, 1:-1].copy()

    def cost_at(self, cell: Cell) -> int:
        if not in_bounds(self._shape, cell):
            return int(INF)
        return int(self.g_r[cell[0] + 1, cell[1] + 1])

    def path(self, start: Cell) -> np.ndarray:
        start = (int(start[0]), int(start[1]))
        if not in_bounds(self._shape, start) or self.cost_at(start) >= INF:
            return np.empty((0, 2), dtype=np.int32)
        width = self._shape[1] + 2
        off = (NEIGHBOUR_DR.astype(np.int64) * width + NEIGHBOUR_DC).astype(np.int64)
        s = (start[0] + 1) * width + start[1] + 1
        g, blk = self.g_r.reshape(-1), self.blocked_map.reshape(-1).view(np.uint8)
        return dial.path_cells(blk, g, off, NEIGHBOUR_COST.astype(np.int64), s, width)
