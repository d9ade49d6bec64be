"""A seeded city quarter: blocks of buildings (known), streets and squares, clutter on the way.

Outdoors in a town the map knows the buildings, but not what stands on the pavement today:
parked bicycles, bins, a sign, a delivery. So here the known map is the buildings, and the
``unknown`` fraction of the open ground is covered by small unknown obstacles (up to 60 cm)
that the sensor finds on the way, placed and checked as the courtyard's are
(``scatter_blobs``): start and goal stay connected with the user's inflation.

The quarter is 40 m x 40 m (``EXTENT_M``), drawn at 20 cm (200 x 200 base cells) and
resampled to any grid side. Streets 3 to 5 m wide run north-south and east-west at seeded
spacings (blocks 5 to 9 m); the blocks at the edges run off the map. A block is a building
(``BUILDING_P``), sometimes cut by a 2 m passage; else it is a square with a known kiosk or
fountain in the middle. The start is on the south-west-most crossing, the goal on the
north-east-most one.
"""

from __future__ import annotations

import numpy as np

from daemon.planning.grid import FREE, OCCUPIED, UNKNOWN, Cell
from daemon.planning.inflation import dilate, radius_in_cells

from .courtyard import (
    SENSOR_RANGE_M,
    USER_RADIUS_M,
    Scenario,
    connected,
    resample,
    scale_cell,
    scatter_blobs,
)

EXTENT_M = 40.0
"""Side of the quarter in metres, whatever the grid."""
BASE_CELL_M = 0.2
N = round(EXTENT_M / BASE_CELL_M)
"""Base cells per side (200)."""
MIN_GRID = 80
"""Coarsest grid side: 50 cm cells, where a 3 m street is still six cells."""
STREET_MIN, STREET_MAX = 15, 25
"""Street widths, base cells (3 m to 5 m)."""
BLOCK_MIN, BLOCK_MAX = 25, 45
"""Block sides, base cells (5 m to 9 m); the edge blocks, cut by the map, 2.4 m to 5 m."""
BUILDING_P = 0.8
"""Chance that a block is built on; else it is a square."""
PASSAGE_P = 0.3
"""Chance that a building is cut in two by a passage."""
PASSAGE = 10
"""Passage width, base cells (2 m)."""
BLOB_MAX = 3
"""Largest unknown obstacle side, base cells (60 cm)."""


def _bands(rng: np.random.Generator) -> tuple[list[tuple[int, int]], list[tuple[int, int]]]:
    """Streets and blocks across [0, N), half-open: block, street, block, ..., street, block.

    The quarter is cut out of a town: the blocks at its edges run off the map, so a walk
    goes through the streets, not round a free margin.
    """
    streets, blocks = [], []
    x = int(rng.integers(BLOCK_MIN // 2, BLOCK_MIN + 1))
    blocks.append((0, x))
    while True:
        w = int(rng.integers(STREET_MIN, STREET_MAX + 1))
        streets.append((x, x + w))
        x += w
        # leave room for a street and an edge block after this one, else this is the edge
        b = min(int(rng.integers(BLOCK_MIN, BLOCK_MAX + 1)), N - x - STREET_MAX - BLOCK_MIN // 2)
        if N - x <= BLOCK_MAX or b < BLOCK_MIN:
            blocks.append((x, N))
            return streets, blocks
        blocks.append((x, x + b))
        x += b


def _mid(band: tuple[int, int]) -> int:
    return (band[0] + band[1]) // 2


def _layout(seed: int) -> tuple[np.ndarray, Cell, Cell]:
    """Buildings and squares' kiosks (base map, OCCUPIED and FREE), start and goal."""
    rng = np.random.default_rng([seed, 0x57])
    row_streets, row_blocks = _bands(rng)
    col_streets, col_blocks = _bands(rng)
    town = np.full((N, N), FREE, dtype=np.uint8)
    for r0, r1 in row_blocks:
        for c0, c1 in col_blocks:
            big = min(r1 - r0, c1 - c0) >= BLOCK_MIN  # edge blocks may be cut small
            if rng.random() < BUILDING_P or not big:
                town[r0:r1, c0:c1] = OCCUPIED
                if big and rng.random() < PASSAGE_P:
                    if rng.random() < 0.5:
                        p = int(rng.integers(r0 + 6, r1 - 6 - PASSAGE + 1))
                        town[p : p + PASSAGE, c0:c1] = FREE
                    else:
                        p = int(rng.integers(c0 + 6, c1 - 6 - PASSAGE + 1))
                        town[r0:r1, p : p + PASSAGE] = FREE
            else:  # a square, with a kiosk or fountain of 1.6 to 3 m in the middle
                h, w = (int(v) for v in rng.integers(8, 16, size=2))
                rc, cc = (r0 + r1) // 2, (c0 + c1) // 2
                town[rc - h // 2 : rc - h // 2 + h, cc - w // 2 : cc - w // 2 + w] = OCCUPIED
    start = (_mid(row_streets[-1]), _mid(col_streets[0]))
    goal = (_mid(row_streets[0]), _mid(col_streets[-1]))
    return town, start, goal


def check_grid(grid: int) -> None:
    """ValueError unless the streets can be drawn at ``grid`` cells per side."""
    if grid < MIN_GRID:
        raise ValueError(
            f"streets: grid must be at least {MIN_GRID} cells per side "
            f"({EXTENT_M / MIN_GRID:.2f} m cells), got {grid}"
        )


def make_streets(
    grid: int = 100,
    unknown: float = 0.4,
    seed: int = 0,
    radius_m: float = USER_RADIUS_M,
    sensor_range_m: float = SENSOR_RANGE_M,
) -> Scenario:
    """The quarter of ``seed`` at ``grid`` cells per side (any side from ``MIN_GRID``).

    The streets and buildings depend on ``seed`` only, the obstacles on the pavement on
    ``seed`` and ``unknown``, so every grid walks the same quarter.
    """
    check_grid(grid)
    if not 0.0 <= unknown < 1.0:
        raise ValueError(f"unknown must be in [0, 1), got {unknown}")
    cell_m = EXTENT_M / grid
    radius = radius_in_cells(radius_m, cell_m)
    town, start_b, goal_b = _layout(seed)
    start, goal = scale_cell(start_b, N, grid), scale_cell(goal_b, N, grid)
    known = resample(np.where(town == OCCUPIED, OCCUPIED, UNKNOWN).astype(np.uint8), grid)
    if not connected(dilate(known == OCCUPIED, radius), start, goal):  # streets are wide
        raise ValueError(f"streets: no way from start to goal at grid {grid}")
    rng = np.random.default_rng([seed, round(unknown * 1000), 0x57])
    true, coverage = scatter_blobs(town, grid, (start_b, goal_b), unknown, rng, BASE_CELL_M,
                                   radius_m, BLOB_MAX)  # fmt: skip
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
        name="streets",
    )
