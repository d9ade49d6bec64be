"""The planning grid's conventions: cells, costs, neighbour order, metres.

Every planner (reference Dijkstra, CPU, CUDA) and every consumer of a path reads
these constants, so CPU and GPU agree bit for bit.

Conventions
- A cell is ``(row, col)``; row 0 is the top (north) edge of the map, so "start at the
  bottom, goal at the top" means a large start row and a small goal row.
- Flat index ``i = row * width + col`` (C order), the layout of every map array.
- Occupancy is ``uint8``: FREE, OCCUPIED or UNKNOWN. Unknown is treated as free, as in
  Díaz-Toro et al. 2022: the user walks on and the sensor corrects the map.
- The planner sees only a boolean ``blocked`` map: occupancy inflated by the user's
  radius (see ``inflation.py``). An edge u→v exists when neither u nor v is blocked.
  Diagonal moves need no free corners: inflation by the user's radius already keeps
  the body clear of the corners, and the paper's 8-connected grid allows them.
- Costs: 10 straight, 14 diagonal (the paper's integers), ``int32``; the goal is 0;
  unreachable and blocked cells hold ``INF``.
- Metres: x east, y north, origin at the map's south-west corner; heading in radians,
  0 = east, counter-clockwise positive (REP 103).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

CELL_M = 0.10
"""Default cell size in metres."""

FREE = np.uint8(0)
OCCUPIED = np.uint8(1)
UNKNOWN = np.uint8(2)

STRAIGHT = 10
DIAGONAL = 14
INF = np.int32(0x3FFFFFFF)
"""Unreachable. Far below int32 max so that ``INF + DIAGONAL`` cannot overflow."""

# The fixed neighbour order. Ties between equal-cost predecessors are broken by the
# first neighbour in this order, on every backend, so all of them give the same path.
NEIGHBOUR_DR = np.array([-1, -1, -1, 0, 0, 1, 1, 1], dtype=np.int32)
NEIGHBOUR_DC = np.array([-1, 0, 1, -1, 1, -1, 0, 1], dtype=np.int32)
NEIGHBOUR_COST = np.array([14, 10, 14, 10, 10, 14, 10, 14], dtype=np.int32)
NO_PRED = np.int8(-1)
"""``pred`` value of the goal, of blocked cells and of unreachable cells."""

Cell = tuple[int, int]


def in_bounds(shape: tuple[int, int], cell: Cell) -> bool:
    r, c = cell
    return 0 <= r < shape[0] and 0 <= c < shape[1]


def cell_to_xy(shape: tuple[int, int], cell: Cell, cell_m: float = CELL_M) -> tuple[float, float]:
    """Centre of ``cell`` in metres."""
    r, c = cell
    return ((c + 0.5) * cell_m, (shape[0] - r - 0.5) * cell_m)


def xy_to_cell(shape: tuple[int, int], x: float, y: float, cell_m: float = CELL_M) -> Cell:
    """The cell containing the point (x, y); may be out of bounds — check with in_bounds.

    A point so far out that the division overflows (1e308 m) is simply out of bounds."""
    col, row = x / cell_m, y / cell_m
    if not (math.isfinite(col) and math.isfinite(row)):
        return (-1, -1)
    return (shape[0] - 1 - math.floor(row), math.floor(col))


def path_cost(path: np.ndarray) -> int:
    """Sum of 10/14 step costs along a ``(k, 2)`` path of adjacent cells.

    Compiled: the navigator sums every step's path (hundreds of cells) to report g at the
    user's cell without asking the device for it.
    """
    cost = _path_cost(np.asarray(path)) if len(path) >= 2 else 0
    if cost < 0:
        raise ValueError("path has a step between non-adjacent cells")
    return int(cost)


@njit(cache=True, nogil=True)
def _path_cost(path: np.ndarray) -> int:  # pragma: no cover - compiled
    total = 0
    for i in range(1, path.shape[0]):
        dr = abs(int(path[i, 0]) - int(path[i - 1, 0]))
        dc = abs(int(path[i, 1]) - int(path[i - 1, 1]))
        if dr > 1 or dc > 1 or dr + dc == 0:
            return -1
        total += DIAGONAL if dr + dc == 2 else STRAIGHT
    return total


def checked_plan_input(blocked: np.ndarray, goal: Cell) -> tuple[np.ndarray, tuple[int, int], Cell]:
    """``(blocked as bool, shape, goal as ints)`` for ``plan``; ValueError on a bad map or goal."""
    blocked = np.asarray(blocked, dtype=bool)
    if blocked.ndim != 2 or blocked.size == 0:
        raise ValueError(f"blocked must be a non-empty 2-D map, got shape {blocked.shape}")
    shape = (int(blocked.shape[0]), int(blocked.shape[1]))
    goal = (int(goal[0]), int(goal[1]))
    if not in_bounds(shape, goal):
        raise ValueError(f"goal {goal} is outside the {shape[0]}x{shape[1]} map")
    return blocked, shape, goal


def checked_update_input(
    shape: tuple[int, int], cells: np.ndarray, blocked: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """``(cells as int64, blocked as bool, one per cell)`` for ``update`` on a map of
    ``shape`` that was planned (``(0, 0)``: not yet, RuntimeError); IndexError off the map."""
    if shape == (0, 0):
        raise RuntimeError("call plan(blocked, goal) before update")
    cells = np.asarray(cells, dtype=np.int64).ravel()
    values = np.broadcast_to(np.asarray(blocked, dtype=bool).ravel(), cells.shape)
    h, w = shape
    if cells.size and (cells.min() < 0 or cells.max() >= h * w):
        raise IndexError(f"a cell index is outside the {h}x{w} map")
    return cells, values
