"""Where a goal is on the user's map: a cell, a point in metres or a landmark's name, checked
against the map it must be reached on."""

from __future__ import annotations

from collections.abc import Mapping

from daemon.planning.grid import Cell, in_bounds, xy_to_cell
from daemon.planning.inflation import InflatedMap
from protocol.messages import Goal, GoalCell, GoalLandmark, GoalMetres, StatusCode

from .outcomes import Rejection


def goal_cell(
    goal: Goal, grid: InflatedMap, cell_m: float, landmarks: Mapping[str, tuple[float, float]]
) -> Cell | Rejection:
    """The goal's cell, or why there is none: an unknown landmark, off the map, or a cell
    the user cannot stand in (an obstacle, or within the user's radius of one)."""
    target, shape = goal.target, grid.shape
    if isinstance(target, GoalCell):
        cell = (target.row, target.col)
    elif isinstance(target, GoalMetres):
        cell = xy_to_cell(shape, target.x, target.y, cell_m)
    elif isinstance(target, GoalLandmark):
        where = landmarks.get(target.name)
        if where is None:
            return Rejection(StatusCode.UNKNOWN_LANDMARK, f"no landmark {target.name!r}")
        cell = xy_to_cell(shape, where[0], where[1], cell_m)
    if not in_bounds(shape, cell):
        return Rejection(StatusCode.GOAL_OFF_MAP, f"goal cell {cell} is outside {shape}")
    if grid.blocked[cell]:
        what = "an obstacle" if grid.occupancy[cell] == 1 else "too close to one"
        return Rejection(StatusCode.GOAL_IN_OBSTACLE, f"goal cell {cell} is {what}")
    return (int(cell[0]), int(cell[1]))
