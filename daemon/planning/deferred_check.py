"""The deferred-blocks rule's checks (``deferred_blocks.py``), each one compiled pass.

Each has one explicit signature, compiled at import: a delta of another form is a TypeError,
which the wrapper normalises, never a compile inside a step. As numpy calls the same checks
cost a walking step ~15 µs more on a GPU host, a tenth of its time there.
"""

from __future__ import annotations

import numpy as np
from numba import njit

_FLAGS = "boolean[::1]"
_CELLS = "int64[::1]"


@njit(cache=True, nogil=True, inline="always")
def _rule_holds(  # pragma: no cover - compiled
    flat: np.ndarray, at: int, s: int, on: np.ndarray, cells: np.ndarray, blocked: np.ndarray
) -> int:
    """The rule's conditions for a step from cell ``s`` against P's flat cells ``flat`` (the
    user last at ``at``; the suffix marked in ``on``): the user's index in P if they hold,
    else -1. The cells the user walked past are unmarked either way (they left the suffix)."""
    k = flat.shape[0]
    j = at
    while j < k and flat[j] != s:  # (a) usually at or one further on
        j += 1
    if j == k:
        return -1  # off P, or behind the user's last cell on it
    for i in range(at, j):
        on[flat[i]] = False
    n = on.shape[0]
    for i in range(cells.shape[0]):  # (b) every cell blocked, (c) none on the suffix
        cell = cells[i]
        if not blocked[i] or cell < 0 or cell >= n or on[cell]:
            return -1
    return j


@njit(
    f"UniTuple(int64, 2)({_CELLS}, int64, int64, {_FLAGS}, {_CELLS}, {_FLAGS}, {_FLAGS}, {_CELLS},"
    " int64)",
    cache=True,
    nogil=True,
)
def defer_step(  # pragma: no cover - compiled
    flat: np.ndarray,
    at: int,
    s: int,
    on: np.ndarray,
    cells: np.ndarray,
    blocked: np.ndarray,
    is_pending: np.ndarray,
    pending: np.ndarray,
    count: int,
) -> tuple[int, int]:
    """The rule for a step from cell ``s`` with the delta ``cells``/``blocked``, against P's
    flat cells ``flat`` (the user last at ``at``) and its suffix's marks ``on``.

    Holds: returns the user's index in P and the new count of ``pending``, where the delta's
    cells not already pending were added. Fails: ``(-1, count)``, nothing added; the cells the
    user walked past are unmarked either way (they left the suffix; P stays valid). ``-2``:
    ``blocked`` is not one value a cell, nothing done. A cell outside the map fails the rule
    (the inner planner's step raises the IndexError)."""
    if blocked.shape[0] != cells.shape[0]:
        return -2, count  # not one value a cell: the caller's to make so
    j = _rule_holds(flat, at, s, on, cells, blocked)
    if j < 0:
        return -1, count
    for i in range(cells.shape[0]):
        cell = cells[i]
        if not is_pending[cell]:  # a cell blocked again is pending once
            is_pending[cell] = True
            pending[count] = cell
            count += 1
    return j, count


@njit(f"boolean({_CELLS}, int64, {_FLAGS}, {_CELLS}, {_FLAGS})", cache=True, nogil=True)
def misses_suffix(  # pragma: no cover - compiled
    suffix: np.ndarray, s: int, on: np.ndarray, cells: np.ndarray, blocked: np.ndarray
) -> bool:
    """Whether a step from cell ``s`` with the delta ``cells``/``blocked`` would have passed
    the rule against P's suffix ``suffix`` (its cells marked in ``on``), asked after a step
    that repaired without the check. Unmarks the cells of ``suffix`` before ``s``, as
    ``defer_step`` does: the caller clears the rest of the suffix's marks next."""
    if blocked.shape[0] != cells.shape[0]:
        return False
    return _rule_holds(suffix, 0, s, on, cells, blocked) >= 0
