"""A seeded building: rooms off two corridors, doors the map says are open and some are shut.

The courtyard tests a walk around obstacles nobody mapped. Indoors the surprise is a
different one: the floor plan is known, but a door on it turns out to be closed, and the
user has to go back and round through other rooms. So here the known map is the plan with
every door open, and in the true world a seeded choice of doors is closed; the walker finds
a closed door only when its sensor sees it, and the planner must re-route.

The layout is 20 m x 20 m (``EXTENT_M``), drawn at 10 cm (200 x 200 base cells) and
resampled to any grid side, so the user's radius and the sensor's range scale in cells as
the courtyard's do. From north to south: a band of rooms, a corridor, a band of rooms cut
by a connecting corridor, a second corridor, a band of rooms. Every room has a door onto
each corridor it touches; neighbouring rooms share a door by a seeded coin. The start is in
the south-west room, the goal in the north-east one.

Doors are closed (``CLOSE_P`` each, in a seeded order) only while start and goal stay
connected with the user's inflation. One door on the route the known map plans is always
among them when closing one keeps the two connected, so the walk does re-route. The
``unknown`` fraction adds small unknown blobs as the courtyard does (``scatter_blobs``).
"""

from __future__ import annotations

from itertools import pairwise

import numpy as np

from daemon.planning.grid import FREE, OCCUPIED, UNKNOWN, Cell
from daemon.planning.inflation import dilate, radius_in_cells

from .courtyard import (
    SENSOR_RANGE_M,
    USER_RADIUS_M,
    Scenario,
    bfs_path,
    connected,
    resample,
    scale_cell,
    scatter_blobs,
)

EXTENT_M = 20.0
"""Side of the building in metres, whatever the grid."""
BASE_CELL_M = 0.1
N = round(EXTENT_M / BASE_CELL_M)
"""Base cells per side (200)."""
MIN_GRID = 100
"""Coarsest grid side: 20 cm cells. At 25 cm a 1.2 m door, one cell of it lost to a wall
that straddles a cell, no longer passes a 0.3 m user inflated to two cells."""
OUTER = 2
"""Outer wall thickness, base cells (20 cm)."""
CORRIDOR = 20
"""Corridor width, base cells (2 m)."""
DOOR = 12
"""Door width, base cells (1.2 m)."""
ROOM_MIN, ROOM_MAX = 32, 55
"""Room widths along a band, base cells (3.2 m to 5.5 m)."""
NEIGHBOUR_DOOR_P = 0.5
"""Chance that two neighbouring rooms share a door."""
CLOSE_P = 0.3
"""Chance that a door (beyond the one on the known route) turns out to be closed."""

Rect = tuple[int, int, int, int]
"""(row0, row1, col0, col1), half-open, base cells."""


def _split(a: int, b: int, rng: np.random.Generator) -> list[tuple[int, int]]:
    """Cut the span [a, b) into rooms of ROOM_MIN..ROOM_MAX with a one-cell wall between."""
    rooms = []
    x = a
    while True:
        w = int(rng.integers(ROOM_MIN, ROOM_MAX + 1))
        if b - (x + w + 1) < ROOM_MIN:
            rooms.append((x, b))
            return rooms
        rooms.append((x, x + w))
        x += w + 1


def _door_along(lo: int, hi: int, rng: np.random.Generator) -> int:
    """First cell of a door in a wall spanning [lo, hi), kept two cells off its ends."""
    return int(rng.integers(lo + 2, max(lo + 3, hi - 2 - DOOR + 1)))


def _layout(seed: int) -> tuple[np.ndarray, list[Rect], Cell, Cell]:
    """Walls (base map, OCCUPIED and FREE) with every door open, the doors, start and goal."""
    rng = np.random.default_rng([seed, 0xB1D])
    walls = np.full((N, N), FREE, dtype=np.uint8)
    walls[:OUTER], walls[-OUTER:], walls[:, :OUTER], walls[:, -OUTER:] = (OCCUPIED,) * 4
    lo, hi = OUTER, N - OUTER
    d_a, d_c = (int(d) for d in rng.integers(44, 55, size=2))
    # rows: band A | wall | corridor 1 | wall | band B | wall | corridor 2 | wall | band C
    a = (lo, lo + d_a)
    c1 = (a[1] + 1, a[1] + 1 + CORRIDOR)
    c = (hi - d_c, hi)
    c2 = (c[0] - 1 - CORRIDOR, c[0] - 1)
    b = (c1[1] + 1, c2[0] - 1)
    for row in (a[1], c1[1], b[1], c2[1]):
        walls[row, lo:hi] = OCCUPIED
    # a corridor through band B joins the two
    vx = int(rng.integers(60, 121))
    walls[b[0] : b[1], vx - 1] = walls[b[0] : b[1], vx + CORRIDOR] = OCCUPIED
    walls[c1[1], vx : vx + CORRIDOR] = walls[b[1], vx : vx + CORRIDOR] = FREE

    doors: list[Rect] = []
    bands = [
        (a, _split(lo, hi, rng), (a[1],)),
        (b, _split(lo, vx - 1, rng) + _split(vx + CORRIDOR + 1, hi, rng), (c1[1], b[1])),
        (c, _split(lo, hi, rng), (c2[1],)),
    ]
    for (r0, r1), rooms, corridor_walls in bands:
        for x0, x1 in rooms:
            for row in corridor_walls:
                d = _door_along(x0, x1, rng)
                doors.append((row, row + 1, d, d + DOOR))
        for i, ((_, x1), (n0, _)) in enumerate(pairwise(rooms)):
            walls[r0:r1, x1] = OCCUPIED
            if x1 + 1 != n0:  # the connecting corridor lies between: a door into it
                forced = False
                walls[r0:r1, n0 - 1] = OCCUPIED
            else:
                # the start and goal rooms always have a second way out
                forced = (i == 0 and (r0, r1) == c) or (i == len(rooms) - 2 and (r0, r1) == a)
            if forced or rng.random() < NEIGHBOUR_DOOR_P:
                d = _door_along(r0, r1, rng)
                col = x1 if x1 + 1 == n0 else (x1 if rng.random() < 0.5 else n0 - 1)
                doors.append((d, d + DOOR, col, col + 1))
    for r0, r1, c0, c1_ in doors:
        walls[r0:r1, c0:c1_] = FREE
    first, last = bands[2][1][0], bands[0][1][-1]
    start = ((c[0] + c[1]) // 2, (first[0] + first[1]) // 2)
    goal = ((a[0] + a[1]) // 2, (last[0] + last[1]) // 2)
    return walls, doors, start, goal


def _shut(walls: np.ndarray, doors: list[Rect], closed: list[int]) -> np.ndarray:
    out = walls.copy()
    for i in closed:
        r0, r1, c0, c1 = doors[i]
        out[r0:r1, c0:c1] = OCCUPIED
    return out


def _close_doors(
    walls: np.ndarray, doors: list[Rect], ends: tuple[Cell, Cell], seed: int, margin: int
) -> list[int]:
    """Which doors are closed: one on the known route if it may be, then each by a coin.

    A door is closed only if start and goal stay connected on the base map inflated by
    ``margin`` (the user's radius in base cells plus one, as blobs are checked).
    """
    rng = np.random.default_rng([seed, 0xD00])
    start, goal = ends

    def still_connected(closed: list[int]) -> bool:
        return connected(dilate(_shut(walls, doors, closed) == OCCUPIED, margin), start, goal)

    route = bfs_path(dilate(walls == OCCUPIED, margin), start[0] * N + start[1],
                     goal[0] * N + goal[1])  # fmt: skip
    rr, cc = np.divmod(route, N)
    on_route = [
        i for i, (r0, r1, c0, c1) in enumerate(doors)
        if np.any((rr >= r0) & (rr < r1) & (cc >= c0) & (cc < c1))
    ]  # fmt: skip
    closed: list[int] = []
    for i in rng.permutation(on_route):
        if still_connected([int(i)]):
            closed.append(int(i))
            break
    for i in rng.permutation(len(doors)):
        if int(i) not in closed and rng.random() < CLOSE_P and still_connected([*closed, int(i)]):
            closed.append(int(i))
    return closed


def check_grid(grid: int) -> None:
    """ValueError unless the building can be drawn at ``grid`` cells per side."""
    if grid < MIN_GRID:
        raise ValueError(
            f"building: grid must be at least {MIN_GRID} cells per side "
            f"({EXTENT_M / MIN_GRID:.2f} m cells; a door must pass the user), got {grid}"
        )


def make_building(
    grid: int = 100,
    unknown: float = 0.0,
    seed: int = 0,
    radius_m: float = USER_RADIUS_M,
    sensor_range_m: float = SENSOR_RANGE_M,
) -> Scenario:
    """The building of ``seed`` at ``grid`` cells per side (any side from ``MIN_GRID``).

    The rooms, doors and which doors are closed depend on ``seed`` only, so every grid and
    every ``unknown`` fraction walks the same building; the blobs depend on all three.
    """
    check_grid(grid)
    if not 0.0 <= unknown < 1.0:
        raise ValueError(f"unknown must be in [0, 1), got {unknown}")
    cell_m = EXTENT_M / grid
    radius = radius_in_cells(radius_m, cell_m)
    walls, doors, start_b, goal_b = _layout(seed)
    ends = (start_b, goal_b)
    closed = _close_doors(walls, doors, ends, seed, radius_in_cells(radius_m, BASE_CELL_M) + 1)
    start, goal = scale_cell(start_b, N, grid), scale_cell(goal_b, N, grid)
    # The base check has a cell of margin; should a door still be too narrow at this grid,
    # the latest closed door opens again (deterministic, as the blobs are removed).
    while not connected(dilate(resample(_shut(walls, doors, closed), grid) == OCCUPIED, radius),
                        start, goal):  # fmt: skip
        if not closed:
            raise ValueError(f"building: no way from start to goal at grid {grid}")
        closed.pop()
    rng = np.random.default_rng([seed, round(unknown * 1000), 0xB1D])
    true, coverage = scatter_blobs(_shut(walls, doors, closed), grid, ends, unknown, rng,
                                   BASE_CELL_M, radius_m)  # fmt: skip
    known_base = np.where(walls == OCCUPIED, OCCUPIED, UNKNOWN).astype(np.uint8)
    return Scenario(
        known=resample(known_base, grid),
        true=true,
        start=start,
        goal=goal,
        cell_m=cell_m,
        radius_cells=radius,
        sensor_range_cells=sensor_range_m / cell_m,
        unknown=float(unknown),
        coverage=coverage,
        seed=int(seed),
        name="building",
    )


def building_doors(seed: int = 0, radius_m: float = USER_RADIUS_M) -> tuple[list[Rect], list[int]]:
    """The doors of the building of ``seed`` (base cells) and which are closed at base."""
    walls, doors, start, goal = _layout(seed)
    margin = radius_in_cells(radius_m, BASE_CELL_M) + 1
    return doors, _close_doors(walls, doors, (start, goal), seed, margin)
