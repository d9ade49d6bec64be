"""The harmonic field's relaxation on the CPU (numba): Hong & DeSouza's eq. (1), in log space.

The paper's potential ``u`` is 0 at the goal, 1 on obstacles, and each free cell relaxes to
the mean of its four neighbours (eq. (1)). Far from the goal ``1 − u`` shrinks geometrically
through every narrow passage, and a float cannot hold ``u`` once ``1 − u`` is below its
epsilon (6e-8 in float32, 1e-16 in float64; underflow of ``1 − u`` itself follows at 1e-38 and
1e-308): the field is flat there, the descent finds no lower neighbour, and there is no path.

What these kernels keep instead is ``w = −ln(1 − u)``: 0 at the goal, +inf on obstacles. The
mean of eq. (1) becomes a log-sum-exp, ``w = m + ln 4 − ln Σ exp(−(w_k − m))`` with ``m`` the
smallest neighbour, which never underflows: ``w`` grows about linearly with the distance from
the goal instead of ``1 − u`` shrinking exponentially. The fixed point is the same harmonic
field (``u = 1 − exp(−w)``), and ``w`` is a monotone function of ``u``, so the paper's Idx
(the neighbour of lowest potential) and its descent are unchanged.

Sweeps (``order``):
- ``ORDER_RB``: four-colour SOR (red–black for the nine-point stencil: row and column
  parity), each cell moved ``omega`` times the way to its target. A colour reads only the
  others, so every cell of a colour updates in parallel (the GPU kernel does exactly this).
- ``ORDER_ROWS``: the paper's sequential row-wise form (§II-A), in place from the top-left,
  Gauss–Seidel (``omega`` 1), for comparison.
- ``ORDER_JACOBI``: eq. (1) as written, every cell from the last sweep's values.

``linear`` runs the same sweeps on ``u`` itself (the paper's form, any float type): what the
plateau measurement compares against. Arrays are padded by one ring of obstacles.
"""

from __future__ import annotations

import math

import numba
import numpy as np

ORDER_RB = 0
ORDER_ROWS = 1
ORDER_JACOBI = 2
ORDERS = {"rb": ORDER_RB, "rows": ORDER_ROWS, "jacobi": ORDER_JACOBI}

BLOCKED_W = 1.0e30
"""``w`` of an obstacle (``u`` = 1): larger than any free cell's, finite so arithmetic stays
defined; ``exp(−BLOCKED_W)`` is 0 in every float type."""
LN4 = math.log(4.0)
MID_W = math.log(2.0)
"""The paper's initial free-space value, ``u`` = 0.5 ("the median range")."""


ORTHO = 0.2
DIAG = 0.05
"""The nine-point stencil's weights (4 : 1, over 20): eq. (1)'s mean over guidebelt's
8-connected grid (``grid.py``: a diagonal step needs no free corner), the most isotropic
of the 3 x 3 Laplacians. The paper's four neighbours alone cannot pass a gap two obstacles
leave corner to corner, which guidebelt's grid (and EDS) walks through."""


@numba.njit(cache=True, nogil=True, fastmath=True, inline="always")
def _target(w: np.ndarray, i: int, width: int) -> float:
    """The log-space weighted mean of the eight neighbours of flat cell ``i`` (BLOCKED_W if
    all of them are blocked): ``m − ln Σ a_k exp(−(w_k − m))``, ``m`` the smallest."""
    n, s, e, o = w[i - width], w[i + width], w[i + 1], w[i - 1]
    ne, nw, se, sw = w[i - width + 1], w[i - width - 1], w[i + width + 1], w[i + width - 1]
    m = min(min(min(n, s), min(e, o)), min(min(ne, nw), min(se, sw)))
    if m >= BLOCKED_W:
        return BLOCKED_W
    total = ORTHO * (math.exp(m - n) + math.exp(m - s) + math.exp(m - e) + math.exp(m - o))
    total += DIAG * (math.exp(m - ne) + math.exp(m - nw) + math.exp(m - se) + math.exp(m - sw))
    return m - math.log(total)


@numba.njit(cache=True, nogil=True)
def has_pit(w: np.ndarray, fixed: np.ndarray, width: int) -> bool:
    """Whether some free (not fixed) cell has no strictly lower neighbour: a cell where the
    descent would stop short. Without one, every descent from a free cell strictly falls
    until a fixed cell below ``BLOCKED_W``, and the goal is the only such cell."""
    for i in range(width, w.size - width):
        if fixed[i]:
            continue
        wi = w[i]
        lower = False
        for d in range(9):
            if w[i + (d // 3 - 1) * width + d % 3 - 1] < wi:
                lower = True
                break
        if not lower:
            return True
    return False


@numba.njit(cache=True, nogil=True)
def relax_log(
    w: np.ndarray,
    fixed: np.ndarray,
    width: int,
    order: int,
    omega: float,
    sweeps: int,
    check_every: int,
    tol: float,
    scratch: np.ndarray,
    budget: int,
) -> tuple[int, float, bool]:
    """Sweep the padded flat field ``w`` until the residual — the largest ``|target − w|``
    over free cells, in log units, i.e. the relative residual of ``1 − u`` — is below ``tol``
    (checked every ``check_every`` sweeps) or ``sweeps`` are done; or, once ``budget`` sweeps
    are done, at the first check that finds no pit (``has_pit``). Returns (sweeps, residual,
    whether it ended without a pit). ``scratch``: a buffer like ``w`` (Jacobi's last sweep)."""
    n = w.size
    height = n // width
    residual = math.inf
    done = 0
    while done < sweeps:
        check = (done + 1) % check_every == 0 or done + 1 == sweeps
        worst = 0.0
        if order == ORDER_JACOBI:
            scratch[:] = w
            for i in range(width, n - width):
                if not fixed[i]:
                    t = _target(scratch, i, width)
                    if check:
                        worst = max(worst, abs(t - w[i]) if t < BLOCKED_W else 0.0)
                    w[i] = t
        elif order == ORDER_ROWS:
            for i in range(width, n - width):
                if not fixed[i]:
                    t = _target(w, i, width)
                    if check and t < BLOCKED_W:
                        worst = max(worst, abs(t - w[i]))
                    w[i] = t
        else:
            for colour in range(4):
                for r in range(1 + (colour >> 1), height - 1, 2):
                    start = r * width + 1 + (colour & 1)
                    for i in range(start, (r + 1) * width - 1, 2):
                        if fixed[i]:
                            continue
                        t = _target(w, i, width)
                        old = w[i]
                        if t >= BLOCKED_W:
                            w[i] = BLOCKED_W
                            continue
                        if check:
                            worst = max(worst, abs(t - old) if old < BLOCKED_W else 0.0)
                        # Over-relax only where the cell already has a value: from "unknown"
                        # (BLOCKED_W, a cell just freed) it takes its target as it is.
                        new = t if old >= BLOCKED_W else old + omega * (t - old)
                        w[i] = max(new, 0.0)
        done += 1
        if check:
            residual = worst
            if residual < tol:
                break
            if done >= budget and not has_pit(w, fixed, width):
                return done, residual, True
    return done, residual, residual < tol


@numba.njit(cache=True, nogil=True)
def relax_linear(
    u: np.ndarray,
    fixed: np.ndarray,
    width: int,
    order: int,
    omega: float,
    sweeps: int,
    check_every: int,
    tol: float,
    scratch: np.ndarray,
) -> tuple[int, float]:
    """The paper's eq. (1) on ``u`` itself (goal 0, obstacles 1), in ``u``'s own float type:
    the same orders and stopping rule as ``relax_log``, the residual absolute in ``u``."""
    n = u.size
    height = n // width
    residual = math.inf
    done = 0
    while done < sweeps:
        check = (done + 1) % check_every == 0 or done + 1 == sweeps
        worst = 0.0
        if order == ORDER_JACOBI:
            scratch[:] = u
        rb = order == ORDER_RB
        for colour in range(4 if rb else 1):
            for r in range(1 + (colour >> 1 if rb else 0), height - 1, 2 if rb else 1):
                step = 2 if rb else 1
                start = r * width + 1 + ((colour & 1) if rb else 0)
                for i in range(start, (r + 1) * width - 1, step):
                    if fixed[i]:
                        continue
                    src = scratch if order == ORDER_JACOBI else u
                    ortho = src[i - width] + src[i + width] + src[i - 1] + src[i + 1]
                    diag = (src[i - width - 1] + src[i - width + 1] + src[i + width - 1]
                            + src[i + width + 1])  # fmt: skip
                    t = ortho * ORTHO + diag * DIAG
                    old = u[i]
                    if check:
                        worst = max(worst, abs(float(t) - float(old)))
                    u[i] = old + omega * (t - old) if order == ORDER_RB else t
        done += 1
        if check:
            residual = worst
            if residual < tol:
                break
    return done, residual


@numba.njit(cache=True, nogil=True)
def bfs_steps(fixed_blocked: np.ndarray, goal: int, width: int, out: np.ndarray) -> None:
    """8-connected steps from the goal to every cell of the padded map (-1: unreachable): the
    cells the harmonic field can reach, and the distance-like first guess of a cold plan."""
    out[:] = -1
    n = out.size
    queue = np.empty(n, dtype=np.int64)
    if fixed_blocked[goal]:
        return
    out[goal] = 0
    head, tail = 0, 1
    queue[0] = goal
    while head < tail:
        cur = queue[head]
        head += 1
        for d in range(9):
            nxt = cur + (d // 3 - 1) * width + d % 3 - 1
            if out[nxt] < 0 and not fixed_blocked[nxt]:
                out[nxt] = out[cur] + 1
                queue[tail] = nxt
                tail += 1


@numba.njit(cache=True, nogil=True)
def descend(w: np.ndarray, width: int, start: int, goal: int, out: np.ndarray) -> int:
    """The paper's path: from ``start`` to the neighbour of lowest potential (Idx), while it is
    strictly lower, until the goal. Writes flat cells into ``out``; returns their count, or -1
    when the descent stops short of the goal (a plateau or a pocket without the goal): no path
    is ever one that climbs or enters an obstacle."""
    cur = start
    k = 0
    while k < out.size:
        out[k] = cur
        k += 1
        if cur == goal:
            return k
        best = cur
        wb = w[cur]
        for d in range(9):
            nxt = cur + (d // 3 - 1) * width + d % 3 - 1
            if w[nxt] < wb:
                best, wb = nxt, w[nxt]
        if best == cur or wb >= BLOCKED_W:
            return -1
        cur = best
    return -1


@numba.njit(cache=True, nogil=True)
def stuck_cells(w: np.ndarray, width: int, reach: np.ndarray, goal: int) -> int:
    """Reachable free cells (``reach >= 0``) with no strictly lower neighbour: where a descent
    would stop short of the goal (the plateau count; 0 on a field fit to plan on)."""
    count = 0
    for i in range(width, w.size - width):
        if reach[i] <= 0 or i == goal:
            continue
        wi = w[i]
        lower = False
        for d in range(9):
            lower = lower or w[i + (d // 3 - 1) * width + d % 3 - 1] < wi
        if not lower:
            count += 1
    return count


@numba.njit(cache=True, nogil=True)
def apply_cells(
    w: np.ndarray, blocked: np.ndarray, cells: np.ndarray, values: np.ndarray, goal: int
) -> int:
    """Set ``blocked[cells] = values`` on the padded map and ready ``w`` for a warm start: a
    newly blocked cell takes ``BLOCKED_W`` (u = 1), a newly freed one ``BLOCKED_W`` too, as
    "no value yet" (the next sweep gives it its neighbours' mean without over-relaxing); every
    other cell keeps the last field. Returns how many cells flipped."""
    flipped = 0
    for k in range(cells.size):
        i = cells[k]
        if blocked[i] != values[k]:
            blocked[i] = values[k]
            flipped += 1
            if i != goal:
                w[i] = BLOCKED_W
    return flipped


@numba.njit(cache=True, nogil=True)
def reach_mask(
    blocked: np.ndarray, goal: int, width: int, steps: np.ndarray, w: np.ndarray, fixed: np.ndarray
) -> int:
    """Recompute which free cells the goal reaches (8-connected) and the relaxation's fixed
    cells: obstacles, the goal, and every free cell the goal cannot reach, which takes
    ``BLOCKED_W`` — its exact value (u = 1): a pocket cut off has no goal to feel, and left
    free it would drift towards 1 forever and keep the residual up. Returns reachable cells."""
    bfs_steps(blocked, goal, width, steps)
    count = 0
    for i in range(w.size):
        if steps[i] < 0:
            fixed[i] = True
            w[i] = BLOCKED_W
        else:
            fixed[i] = i == goal
            count += 1
    return count
