"""A replanning step's bounded repair: fill the basins of a field's pits (priority-flood + ε).

A *pit* is a free cell with no strictly lower neighbour; its *basin* the free cells whose
descent (the paper's Idx, the neighbour of lowest ``w``) ends there. When the sensor reveals
a wall across the way the field drained, a whole region behind it drains into pits at the
wall, and relaxation must lift all of it until it spills the other way: 4 600–10 700 sweeps
at 400² (as many as a plan from scratch). Instead, once a step's sweeps are spent, the
basins are filled at once, as a hydrologist fills a digital elevation model's depressions:

- the basins ``D``: from the pits (and the free cells with no value yet, ``BLOCKED_W``: a
  basin's cell next to one could not fall on it), back along Idx (a cell joins when its Idx
  points into D);
- the seeds: the free cells round D (their descent reaches the goal: a chain of strictly
  falling Idx steps ends at a pit, which would put it in D, or at the goal), and the goal;
- the flood: lowest seed first (a heap), each cell of D the flood meets takes
  ``max(w, w_from + ε)`` — at least ε above the cell it was reached from — and floods on
  from there; raised cells go through a queue, taken whenever its head is not above the
  heap's top.

Barnes, Lehman & Mulla, "Priority-Flood: An optimal depression-filling and watershed-labeling
algorithm for digital elevation models", Computers & Geosciences 62 (2014), the ε variant
(their Algorithm 2 with ε; the improved version's queue for raised cells, but merged with
the heap by value: taken ahead of it regardless, it let a long raised chain outrun a lower
seed). Every cell of D ends strictly above the cell it was
reached from, whose value was final then; cells outside D are untouched and their Idx still
falls towards the goal (D only rose). So the field has no pit and every descent reaches the
goal, whatever the relaxation left: the work is a pass over the basins (``O(|D| log |D|)``),
not sweeps over the grid. In heap order the result is the fixed point ``W(c) = max(w(c),
min over c's neighbours of W + ε)`` on D — the smallest field ≥ ``w`` with an ε-lower
neighbour at every basin cell, which Planchon & Darboux (Catena 46, 2002) reach by iteration
and the GPU's ``harmonic_fill`` by parallel passes — so the later steps' sweeps relax from a
field close to the one they left, towards the harmonic one, and both engines fill alike.
"""

from __future__ import annotations

import numba
import numpy as np

from .relax import BLOCKED_W

EPS = 0.2
"""``w`` (log units) a filled cell takes above the cell the flood reached it from. A filled
basin so has a real slope, which a step's sweeps do not turn back into pits as easily as a
near-flat one: the steeper, the fewer refills (H100, 2000² courtyard walk, steps at omega 1:
fills on 9 of 60 steps at 0.05, 1e-3 at omega 1.3: 58 of 60; CPU, 400² courtyard walk, 10/20
steps, 59 steps: fills on 50 steps and 252 k cells in all at 0.05, 44 and 185 k at 0.1, 22
and 149 k at 0.2, 11 and 113 k at 0.5). The largest fill grows with it (17.7 k, 18.0 k,
22.4 k, 28.3 k cells), and so may a step's tail: 0.2, not 0.5."""


@numba.njit(cache=True, nogil=True)
def _offsets(width: int) -> np.ndarray:
    """The flat offset of Idx step d (0..8, row-major in the 3 x 3 block), as a table, not a
    floor division and modulo in every neighbour loop (a 43 k-cell basin's flood, dev VM, CPU
    time: 3.9 → 3.2 ms)."""
    offs = np.empty(9, dtype=np.int64)
    for d in range(9):
        offs[d] = (d // 3 - 1) * width + d % 3 - 1
    return offs


@numba.njit(cache=True, nogil=True, inline="always")
def _steepest(w: np.ndarray, i: int, offs: np.ndarray) -> int:
    """Cell i's Idx: its first neighbour of lowest ``w`` strictly below its own, 4 when none is
    or that lowest is ``BLOCKED_W``."""
    best, wb = 4, w[i]
    for d in range(9):
        v = w[i + offs[d]]
        if v < wb:
            best, wb = d, v
    return 4 if wb >= BLOCKED_W else best


@numba.njit(cache=True, nogil=True)
def lowest_each(w: np.ndarray, fixed: np.ndarray, width: int, idx: np.ndarray,
                pits: np.ndarray) -> int:  # fmt: skip
    """The CPU's Idx of every cell (the GPU kernel's ``write_idx``: the first neighbour of
    lowest ``w`` strictly below the cell's own, 4 when none is or it is ``BLOCKED_W``) and the
    free pits into ``pits``, with the free cells that have no value yet (``BLOCKED_W``: the
    flood gives them one, and their neighbours in a basin can then fall on them); returns
    their count."""
    idx[:] = 4
    offs = _offsets(width)
    count = 0
    for i in range(width, w.size - width):
        c = i % width
        if c == 0 or c == width - 1:
            continue
        best = _steepest(w, i, offs)
        idx[i] = best
        if (best == 4 or w[i] >= BLOCKED_W) and not fixed[i]:
            pits[count] = i
            count += 1
    return count


@numba.njit(cache=True, nogil=True)
def basins(idx: np.ndarray, fixed: np.ndarray, width: int, pits: np.ndarray, mark: np.ndarray,
           cells: np.ndarray, rings: bool = True) -> tuple[int, int, int]:  # fmt: skip
    """The pits' basins (back along Idx), then every other cell next to them (the ring the
    flood reads), then the cells next to the ring (the ring's Idx reads them), into
    ``cells``: returns the three counts. ``mark``: scratch of zeros, left marked (1 basin,
    2 ring, 4 outer ring) for ``flood``, which clears it. ``rings`` False: the basins alone
    (the device's fill reads their neighbours itself), the two rings' counts 0, ``mark``
    left zeroed. ``pits`` and ``cells`` may be int32 (the device's lists, pinned) or int64.

    Idx is a forest (every cell has one Idx step, to a strictly lower cell), so a cell whose
    step leads into the basin is met once, from the one cell it leads to: only the pits need
    a mark (one may be a cell with no value yet whose step leads into another pit's basin).
    The search so reads ``mark`` only where Idx leads back, and the device's fill (rings
    False) has no mark to clear after it (dev VM, CPU time, the 400² walk's 28 k-cell
    basin: the basins, the mark cleared and the list narrowed to int32, ~0.31 -> ~0.24 ms)."""
    offs = _offsets(width)
    n = 0
    for p in pits:
        if mark[p] == 0:
            mark[p] = 1
            cells[n] = p
            n += 1
    head = 0
    while head < n:
        cur = cells[head]
        head += 1
        for d in range(9):
            j = cur - offs[d]  # j's Idx step d leads to cur
            if idx[j] == d and d != 4 and not fixed[j] and mark[j] == 0:
                if rings:
                    mark[j] = 1
                cells[n] = j
                n += 1
    if not rings:
        for p in pits:
            mark[p] = 0
        return n, 0, 0
    ring = _around(cells, 0, n, mark, 2, offs, width, False)
    outer = _around(cells, n, ring, mark, 4, offs, width, True)
    return n, ring - n, outer - ring


@numba.njit(cache=True, nogil=True, inline="always")
def _around(cells, start, end, mark, label, offs, width, skip_border) -> int:
    """The unmarked neighbours of ``cells[start:end]`` (a border cell's skipped when
    ``skip_border``: its outside neighbours are off the padded map) appended from
    ``cells[end]`` and marked ``label``; returns the new end."""
    out = end
    for k in range(start, end):
        if skip_border and _border(cells[k], width, cells.size):
            continue
        for d in range(9):
            j = cells[k] + offs[d]
            if mark[j] == 0:
                mark[j] = label
                cells[out] = j
                out += 1
    return out


@numba.njit(cache=True, nogil=True, inline="always")
def _border(i: int, width: int, size: int) -> bool:
    c = i % width
    return i < width or i >= size - width or c == 0 or c == width - 1


@numba.njit(cache=True, nogil=True)
def _push(keys: np.ndarray, items: np.ndarray, size: int, key: float, item: int) -> int:
    k = size
    while k > 0:
        parent = (k - 1) >> 1
        if keys[parent] <= key:
            break
        keys[k], items[k] = keys[parent], items[parent]
        k = parent
    keys[k], items[k] = key, item
    return size + 1


@numba.njit(cache=True, nogil=True)
def _pop(keys: np.ndarray, items: np.ndarray, size: int) -> tuple[int, int]:
    top = items[0]
    size -= 1
    key, item = keys[size], items[size]
    k = 0
    while True:
        child = 2 * k + 1
        if child >= size:
            break
        if child + 1 < size and keys[child + 1] < keys[child]:
            child += 1
        if keys[child] >= key:
            break
        keys[k], items[k] = keys[child], items[child]
        k = child
    keys[k], items[k] = key, item
    return top, size


@numba.njit(cache=True, nogil=True)
def flood(w: np.ndarray, width: int, cells: np.ndarray, n_basin: int, n_ring: int,
          n_outer: int, eps: float, mark: np.ndarray, idx: np.ndarray) -> int:  # fmt: skip
    """Fill the basins ``cells[:n_basin]`` of ``w`` (valid there, on the ring
    ``cells[n_basin:n_basin + n_ring]`` and on the outer ring after it; ``mark`` as
    ``basins`` left it, cleared here), write the Idx of the basins and the ring, and return
    how many basin cells the flood did not reach (0: none can be left, every basin borders a
    free cell or the goal). The ring's Idx can change: a basin cell that had no value yet
    may now be the lowest neighbour of a ring cell."""
    total = n_basin + n_ring
    offs = _offsets(width)
    keys = np.empty(total, dtype=np.float64)
    items = np.empty(total, dtype=np.int64)
    queue = np.empty(n_basin, dtype=np.int64)
    size = 0
    for k in range(n_basin, total):
        c = cells[k]
        if w[c] < BLOCKED_W:  # a free cell, or the goal (the only fixed cell below BLOCKED_W)
            size = _push(keys, items, size, w[c], c)
    head = tail = 0
    while head < tail or size > 0:
        # The lower of the queue's head and the heap's top: the queue holds the raised cells
        # in the order they were raised, each ε above a cell taken in increasing order, so it
        # is sorted, and the two together give every cell in increasing order (the raised
        # cells without the heap's log n).
        if head < tail and (size == 0 or w[queue[head]] <= keys[0]):
            c = queue[head]
            head += 1
        else:
            c, size = _pop(keys, items, size)
        v = w[c]
        for d in range(9):
            j = c + offs[d]
            if mark[j] != 1:
                continue
            mark[j] = 3
            # max(w, v + ε), strictly above v in w's own float type (float32 on the GPU
            # rounds v + ε back to v once ε is below half a unit in the last place); a cell
            # with no value yet takes v + ε.
            step = eps
            up = v + step
            while up <= v:
                step *= 2.0
                up = v + step
            if w[j] < BLOCKED_W and w[j] > up:
                size = _push(keys, items, size, w[j], j)
            else:
                w[j] = up
                queue[tail] = j
                tail += 1
    left = 0
    for k in range(n_basin):
        left += mark[cells[k]] != 3
    for k in range(total):
        i = cells[k]
        if _border(i, width, w.size):
            continue
        idx[i] = _steepest(w, i, offs)
    for k in range(total + n_outer):
        mark[cells[k]] = 0
    return left
