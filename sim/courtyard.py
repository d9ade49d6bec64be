"""The paper's experiment as a seeded scenario: a courtyard, unknown obstacles, start and goal.

Díaz-Toro et al. 2022 walk a user across a 10 m x 10 m courtyard mapped at 10 cm
(100 x 100 cells): outer walls, boxes and a garden are KNOWN; small unknown obstacles
are found on the way by a 3 m, 80° sensor. Finer grids (200, 400, 1000, 2000) are the
same physical courtyard at finer cells, so the user's radius and the sensor range scale
in cells while the walk stays the same walk.

Everything is built at the base 100 x 100 resolution and then resampled:
- blobs (small rectangles, 10-30 cm) are placed one at a time in random order until they
  cover the asked fraction of the free area; a blob that would cut the start from the goal
  (checked with the user's radius plus one cell of margin) is skipped;
- at the target resolution the true map is inflated by the user's radius and checked
  again; should a discretisation corner still cut it, the latest blobs are removed.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numba import njit

from daemon.planning.grid import CELL_M, FREE, OCCUPIED, UNKNOWN, Cell
from daemon.planning.inflation import InflatedMap, dilate, radius_in_cells

BASE = 100
"""Cells per side of the paper's courtyard at 10 cm."""
USER_RADIUS_M = 0.30
SENSOR_RANGE_M = 3.0
BLOB_MAX_CELLS = 3
"""Largest blob side at the base resolution (30 cm): "small" unknown obstacles."""

# Base-resolution layout, (row0, row1, col0, col1) inclusive. Row 0 is north (the goal side).
GARDEN = (46, 53, 1, 60)
"""A garden strip from the west wall across most of the courtyard: the straight line is shut."""
BOXES = (
    (44, 55, 78, 84),
    (17, 24, 18, 29),
    (14, 21, 64, 72),
    (70, 78, 28, 39),
    (69, 76, 68, 77),
)
BASE_START: Cell = (93, 50)
BASE_GOAL: Cell = (6, 50)


@dataclass(frozen=True)
class Scenario:
    """One walk: what the user knows, what is really there, where to go.

    Every scenario of ``sim.scenarios`` (the courtyard and the others) is one of these, so
    the walk, the belt walker and the benchmark take any of them unchanged.
    """

    known: np.ndarray
    """``uint8`` occupancy the walk starts from: known obstacles OCCUPIED, the rest UNKNOWN."""
    true: np.ndarray
    """``uint8`` occupancy of the world: known obstacles and unknown blobs OCCUPIED, rest FREE."""
    start: Cell
    goal: Cell
    cell_m: float
    radius_cells: int
    sensor_range_cells: float
    unknown: float
    """The fraction of free area asked to be covered by unknown obstacles."""
    coverage: float
    """The fraction actually covered (blobs that would cut start from goal are skipped)."""
    seed: int
    name: str = "courtyard"
    """Which scenario of ``sim.scenarios`` made it, for rows and pictures."""

    @property
    def shape(self) -> tuple[int, int]:
        return (int(self.known.shape[0]), int(self.known.shape[1]))

    @property
    def grid(self) -> int:
        return self.shape[0]


def base_courtyard() -> np.ndarray:
    """The known 100 x 100 map: walls, garden strip and boxes OCCUPIED, the rest UNKNOWN."""
    known = np.full((BASE, BASE), UNKNOWN, dtype=np.uint8)
    known[0, :] = known[-1, :] = known[:, 0] = known[:, -1] = OCCUPIED
    for r0, r1, c0, c1 in (GARDEN, *BOXES):
        known[r0 : r1 + 1, c0 : c1 + 1] = OCCUPIED
    return known


@njit(cache=True)
def bfs_path(blocked: np.ndarray, start: int, goal: int) -> np.ndarray:
    """Flat cells of some 8-connected path start → goal avoiding blocked; empty if none."""
    h, w = blocked.shape
    flat = blocked.ravel()
    n = h * w
    parent = np.full(n, -2, dtype=np.int64)
    if flat[start] or flat[goal]:
        return np.empty(0, dtype=np.int64)
    queue = np.empty(n, dtype=np.int64)
    head, tail = 0, 1
    queue[0] = start
    parent[start] = -1
    while head < tail:
        cur = queue[head]
        head += 1
        if cur == goal:
            break
        r, c = cur // w, cur % w
        for dr in range(-1, 2):
            for dc in range(-1, 2):
                nr, nc = r + dr, c + dc
                if (dr != 0 or dc != 0) and 0 <= nr < h and 0 <= nc < w:
                    nxt = nr * w + nc
                    if parent[nxt] == -2 and not flat[nxt]:
                        parent[nxt] = cur
                        queue[tail] = nxt
                        tail += 1
    if parent[goal] == -2:
        return np.empty(0, dtype=np.int64)
    length = 0
    cur = goal
    while cur != -1:
        length += 1
        cur = parent[cur]
    out = np.empty(length, dtype=np.int64)
    cur = goal
    for i in range(length - 1, -1, -1):
        out[i] = cur
        cur = parent[cur]
    return out


def connected(blocked: np.ndarray, start: Cell, goal: Cell) -> bool:
    """True when an 8-connected path of unblocked cells joins start and goal."""
    w = blocked.shape[1]
    path = bfs_path(np.ascontiguousarray(blocked, dtype=np.bool_), start[0] * w + start[1],
                     goal[0] * w + goal[1])
    return path.size > 0


def _place_blobs(
    rng: np.random.Generator,
    known: np.ndarray,
    fraction: float,
    margin: int,
    ends: tuple[Cell, Cell],
    blob_max: int,
) -> list[np.ndarray]:
    """Blobs (flat base cells each) covering ``fraction`` of the free area, start ↔ goal kept.

    A blob is tested only when its inflation touches the current start → goal path: a path
    that it misses stays open, so most blobs need no search at all.
    """
    h, w = known.shape
    free = known != OCCUPIED
    reserve = np.zeros_like(free)
    span = margin + 1
    for r, c in ends:
        reserve[max(0, r - span) : r + span + 1, max(0, c - span) : c + span + 1] = True
    allowed = (free & ~reserve).ravel()
    target = round(fraction * int(free.sum()))
    inflated = InflatedMap(known, margin)
    start = ends[0][0] * w + ends[0][1]
    goal = ends[1][0] * w + ends[1][1]
    on_path = np.zeros(h * w, dtype=bool)
    on_path[bfs_path(inflated.blocked, start, goal)] = True
    covered = np.zeros(h * w, dtype=bool)
    n_covered = 0
    blobs: list[np.ndarray] = []
    for anchor in rng.permutation(np.flatnonzero(allowed)):
        if n_covered >= target:
            break
        bh, bw = rng.integers(1, blob_max + 1, size=2)
        if covered[anchor]:
            continue
        r0, c0 = divmod(int(anchor), w)
        rr, cc = np.mgrid[r0 : min(h, r0 + bh), c0 : min(w, c0 + bw)]
        cells = (rr * w + cc).ravel()
        cells = cells[allowed[cells] & ~covered[cells]]
        flipped, _ = inflated.apply(cells, np.full(cells.size, OCCUPIED))
        if on_path[flipped].any():
            path = bfs_path(inflated.blocked, start, goal)
            if path.size == 0:
                inflated.apply(cells, np.full(cells.size, UNKNOWN))
                continue
            on_path[:] = False
            on_path[path] = True
        covered[cells] = True
        n_covered += cells.size
        blobs.append(cells)
    return blobs


def resample(base: np.ndarray, grid: int) -> np.ndarray:
    """The square ``base`` map at ``grid`` cells per side, whatever the ratio of the sides.

    Finer: a cell takes the base cell its centre lies in, so every base cell keeps at least
    one cell (a 10 cm wall stays a wall) and areas keep their size on average (blobs cover
    the fraction asked); for a multiple of the base side this is repetition. Coarser: a cell
    takes OCCUPIED when any base cell it overlaps is, else UNKNOWN when any is, else FREE,
    so an obstacle never thins away (for a divisor, any-pooling). Either way an obstacle of
    a map is one of a map with more obstacles: known ones stay a subset of true ones.
    """
    n = base.shape[0]
    c = np.arange(grid, dtype=np.int64)
    if grid >= n:
        centre = ((2 * c + 1) * n) // (2 * grid)  # as scale_cell
        return np.ascontiguousarray(base[centre][:, centre])
    lo = (c * n) // grid  # first base cell the target cell overlaps
    hi = -(-((c + 1) * n) // grid)  # one past the last (exact integer arithmetic)

    def any_of(mask: np.ndarray) -> np.ndarray:
        s = np.zeros((n + 1, n + 1), dtype=np.int64)
        s[1:, 1:] = mask.cumsum(axis=0).cumsum(axis=1)
        return (s[hi][:, hi] - s[lo][:, hi] - s[hi][:, lo] + s[lo][:, lo]) > 0

    occupied, unknown = any_of(base == OCCUPIED), any_of(base == UNKNOWN)
    out = np.where(occupied, OCCUPIED, np.where(unknown, UNKNOWN, FREE)).astype(np.uint8)
    return np.ascontiguousarray(out)  # the fancy indexing leaves it in Fortran order


def scale_cell(cell: Cell, n: int, grid: int) -> Cell:
    """The ``grid``-side cell holding the centre of ``cell`` of an ``n``-side map."""
    return (((2 * cell[0] + 1) * grid) // (2 * n), ((2 * cell[1] + 1) * grid) // (2 * n))


def scatter_blobs(
    layout: np.ndarray,
    grid: int,
    ends: tuple[Cell, Cell],
    unknown: float,
    rng: np.random.Generator,
    base_cell_m: float,
    radius_m: float = USER_RADIUS_M,
    blob_max: int = BLOB_MAX_CELLS,
) -> tuple[np.ndarray, float]:
    """The true map at ``grid``: ``layout``'s obstacles plus unknown blobs; and their coverage.

    ``layout`` is a square base map (``base_cell_m`` cells) whose OCCUPIED cells are the true
    world's fixed obstacles; ``ends`` (start, goal) are base cells. Every scenario with small
    unknown obstacles shares this, so each is placed and checked the same way (see the module
    docstring): at the base cells with one cell of margin on a finer grid, at the grid's own
    cells on a coarser one, then checked at ``grid`` with the user's inflation, the latest
    blobs removed first should a discretisation corner still cut start from goal.
    """
    n = layout.shape[0]
    cell_m = base_cell_m * n / grid
    radius = radius_in_cells(radius_m, cell_m)
    start, goal = scale_cell(ends[0], n, grid), scale_cell(ends[1], n, grid)
    fixed = resample(layout, grid)
    if grid >= n:
        place, place_ends = layout, ends
        margin, size = radius_in_cells(radius_m, base_cell_m) + 1, blob_max
    else:
        place, place_ends = fixed, (start, goal)
        margin, size = radius, max(1, round(blob_max * grid / n))
    blobs = _place_blobs(rng, place, unknown, margin, place_ends, size)
    while True:
        placed = np.where(place == OCCUPIED, OCCUPIED, FREE).astype(np.uint8)
        for cells in blobs:
            placed.reshape(-1)[cells] = OCCUPIED
        true = resample(placed, grid) if grid >= n else placed
        if connected(dilate(true == OCCUPIED, radius), start, goal) or not blobs:
            break
        blobs.pop()  # deterministic: the latest blob goes first
    free = fixed != OCCUPIED
    coverage = float(np.count_nonzero(free & (true == OCCUPIED)) / max(1, np.count_nonzero(free)))
    return true, coverage


def check_grid(grid: int) -> None:
    """ValueError unless the courtyard can be drawn at ``grid`` cells per side."""
    if grid <= 0 or (grid % BASE != 0 and BASE % grid != 0):
        raise ValueError(f"grid must be a multiple or a divisor of {BASE}, got {grid}")


def make_courtyard(
    grid: int = BASE,
    unknown: float = 0.4,
    seed: int = 0,
    radius_m: float = USER_RADIUS_M,
    sensor_range_m: float = SENSOR_RANGE_M,
) -> Scenario:
    """The courtyard at ``grid`` cells per side (a multiple or divisor of 100), seeded."""
    check_grid(grid)
    if not 0.0 <= unknown < 1.0:
        raise ValueError(f"unknown must be in [0, 1), got {unknown}")
    cell_m = CELL_M * BASE / grid
    radius = radius_in_cells(radius_m, cell_m)
    known = resample(base_courtyard(), grid)
    start, goal = scale_cell(BASE_START, BASE, grid), scale_cell(BASE_GOAL, BASE, grid)
    # Each fraction its own layout, not a superset of the smaller one's.
    rng = np.random.default_rng([seed, round(unknown * 1000)])
    true, coverage = scatter_blobs(base_courtyard(), grid, (BASE_START, BASE_GOAL), unknown,
                                   rng, CELL_M, radius_m)  # fmt: skip
    return Scenario(
        known=known,
        true=true,
        start=start,
        goal=goal,
        cell_m=cell_m,
        radius_cells=radius,
        sensor_range_cells=sensor_range_m / cell_m,
        unknown=float(unknown),
        coverage=coverage,
        seed=int(seed),
    )
