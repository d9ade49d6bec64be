"""The harmonic field on the CPU: numba sweeps (``relax.py``) over padded flat arrays.

The engine interface (the CUDA engine, ``cuda.py``, has the same): ``load`` the fixed cells
(obstacles, cells the goal cannot reach, the goal) and a first field; ``set`` some cells'
value and fixedness (the map's changes, as ``planner.py`` works them out); ``relax`` to the
tolerance, or past a budget of sweeps to a field without a pit; ``fill`` the basins of the
pits a relaxation left (``fill.py``); ``descend`` from a cell; ``field``, a host copy of ``w``;
``relax_start`` and ``undo`` for a relaxation started before the step knows all its changes
(``planner.py``'s overlap), ``fill_start`` for a fill started behind it.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from . import fill as fl
from . import relax as rx


class CpuField:
    backend = "cpu"

    def __init__(self, order: str = "rb", omega: float = 1.3, check_every: int = 5) -> None:
        self.order = rx.ORDERS[order]
        self.omega = float(omega) if order == "rb" else 1.0
        self.check_every = int(check_every)
        self.width = 0
        self.goal = 0

    def load(self, fixed: np.ndarray, w0: np.ndarray, width: int, goal: int) -> None:
        """``fixed``: padded flat bool; ``w0``: the first field (padded flat)."""
        self.width, self.goal = int(width), int(goal)
        self.fixed = fixed.copy()
        self.w = w0.astype(np.float64)
        self.scratch = np.empty_like(self.w)
        self.buf = np.empty(self.w.size, dtype=np.int64)
        self.idx = np.empty(self.w.size, dtype=np.int8)
        self.mark = np.zeros(self.w.size, dtype=np.int8)
        self.cells = np.empty(self.w.size, dtype=np.int64)

    def set(self, cells: np.ndarray, w: float, fixed: bool) -> None:
        self.w[cells] = w
        self.fixed[cells] = fixed

    def relax(self, sweeps: int, tol: float, budget: int | None = None) -> tuple[int, float, bool]:
        """Sweeps, residual, and whether the field ends without a pit (converged, or past
        ``budget`` sweeps with no free cell lacking a lower neighbour; ``relax.has_pit``)."""
        return rx.relax_log(self.w, self.fixed, self.width, self.order, self.omega, sweeps,
                            self.check_every, tol, self.scratch,
                            sweeps if budget is None else budget)  # fmt: skip

    def keep_for_undo(self) -> None:
        """Room for ``relax_start``'s copy of the field (after ``load``)."""
        self.w_kept, self.fixed_kept = np.empty_like(self.w), np.empty_like(self.fixed)

    def relax_start(self, sweeps: int, tol: float, budget: int | None = None,
                    keep: bool = False) -> Callable[[], tuple[int, float, bool]]:  # fmt: skip
        """``relax``, returning what gives its result (the CUDA engine's runs meanwhile; here
        it has run already). ``keep``: ``w`` and the fixedness copied first, for ``undo``."""
        if keep:
            np.copyto(self.w_kept, self.w)
            np.copyto(self.fixed_kept, self.fixed)
        out = self.relax(sweeps, tol, budget)
        return lambda: out

    def undo(self) -> None:
        """The field and fixedness as the last ``relax_start(keep=True)`` found them. What was
        ``set`` before that start is in them here, but not on the CUDA engine (its changes go
        in with the launch): a caller sets them again."""
        np.copyto(self.w, self.w_kept)
        np.copyto(self.fixed, self.fixed_kept)

    def fill(self, eps: float = fl.EPS) -> tuple[int, int]:
        """Fill the basins of the field's pits (``fill.py``); returns the basins' cells and
        those the flood did not reach (0: the field has no pit)."""
        pits = self.buf  # free until the next descent
        count = fl.lowest_each(self.w, self.fixed, self.width, self.idx, pits)
        if count == 0:
            return 0, 0
        counts = fl.basins(self.idx, self.fixed, self.width, pits[:count].copy(), self.mark,
                           self.cells)  # fmt: skip
        left = fl.flood(self.w, self.width, self.cells, *counts, eps, self.mark, self.idx)
        return counts[0], left

    def fill_start(self, eps: float = fl.EPS) -> Callable[[], tuple[int, int]]:
        """``fill`` right behind ``relax_start`` (the CUDA engine launches it so, gated on the
        device by the sweeps' pits); here the relaxation has run already, so it is ``fill``
        now, the function returned gives its answer."""
        out = self.fill(eps)
        return lambda: out

    def descend(self, start: int) -> np.ndarray | None:
        """Flat padded cells of the descent from ``start``; None if it stops short."""
        k = rx.descend(self.w, self.width, start, self.goal, self.buf)
        return None if k < 0 else self.buf[:k].copy()

    def field(self) -> np.ndarray:
        return self.w.copy()
