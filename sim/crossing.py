"""A person steps into the doorway ahead: hold instead of detour, shown.

The user walks north up a corridor (walls 2 m apart, open at the south end) towards a door
5 m ahead, the goal beyond it. When the user is 2.5 m from the door a person walks into the
doorway from the north, stands in it for ``stay_s`` and walks away north again. The only other
way to the goal is back out of the corridor's south end and round the outside: a planner that
replans on what it sees turns the user around, as Hong & DeSouza's wheelchair did. With the
hold, guidance says "wait" and the user stands until the doorway clears.

The loop is the one of ``walks.py`` with a world that changes over time: sensor → inflation →
planner → Guidance → belt walker.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from daemon.planning import make_planner
from daemon.planning.grid import FREE, OCCUPIED, UNKNOWN, cell_to_xy, in_bounds, xy_to_cell
from daemon.planning.inflation import InflatedMap, radius_in_cells

from .belt_walker import BeltWalker, WalkerParams
from .sensor import Sensor
from .walks import STEP_S, path_from

CELL_M = 0.10
SHAPE = (100, 60)
DOOR_ROW = 30
DOOR_COLS = (25, 35)
START = (80, 30)
GOAL = (10, 30)
TRIGGER_M = 2.5
"""The person reaches the doorway when the user is this far from it."""


def corridor_world() -> np.ndarray:
    """True occupancy: outer walls, the corridor (cols 19-20 and 40-41, rows 30-85) and the door
    wall at rows 30-31 with a 1.1 m doorway."""
    occ = np.full(SHAPE, FREE, dtype=np.uint8)
    occ[0, :] = occ[-1, :] = occ[:, 0] = occ[:, -1] = OCCUPIED
    occ[DOOR_ROW:86, 19:21] = OCCUPIED
    occ[DOOR_ROW:86, 40:42] = OCCUPIED
    occ[DOOR_ROW : DOOR_ROW + 2, 19:42] = OCCUPIED
    occ[DOOR_ROW : DOOR_ROW + 2, DOOR_COLS[0] : DOOR_COLS[1] + 1] = FREE
    return occ


def person_rows(t: float, stay_s: float) -> tuple[int, int] | None:
    """Rows covered by the 0.5 m person at ``t`` s after entering the doorway (None: away).

    Walks in from 2 m north at 1 m/s, stands in the doorway ``stay_s``, walks back north.
    """
    if t < -2.0:
        return None
    if t < 0.0:
        top = DOOR_ROW - 2 + round(t * 10)  # 1 m/s = 10 cells/s, arriving at t = 0
    elif t < stay_s:
        top = DOOR_ROW - 2
    elif t < stay_s + 2.0:
        top = DOOR_ROW - 2 - round((t - stay_s) * 10)
    else:
        return None
    return top, top + 5


@dataclass(frozen=True)
class CrossingResult:
    arrived: bool
    walked_m: float
    time_s: float
    holds: int
    backtrack_m: float
    """Largest distance walked back south of the furthest north point reached."""
    collisions: int


def crossing_walk(
    hold: bool = True, stay_s: float = 3.0, seed: int = 0, max_actions: int = 600
) -> CrossingResult:
    from daemon.guidance.guide import Guidance
    from daemon.guidance.hold import HoldPolicy
    from protocol.messages import PatternKind, Pose

    world = corridor_world()
    known = np.where(world == OCCUPIED, OCCUPIED, UNKNOWN).astype(np.uint8)
    radius = radius_in_cells(0.30, CELL_M)
    inflated = InflatedMap(known, radius)
    planner = make_planner("eds", "cpu")
    planner.plan(inflated.blocked, GOAL)
    policy = HoldPolicy() if hold else HoldPolicy(hold_s=0.0)
    guide = Guidance(cell_m=CELL_M, hold=policy)
    sensor = Sensor(3.0 / CELL_M)
    x, y = cell_to_xy(SHAPE, START, CELL_M)
    walker = BeltWalker(x=x, y=y, heading=math.pi / 2, cell_m=CELL_M,
                        params=WalkerParams(), rng=np.random.default_rng(seed))
    door_y = (SHAPE[0] - DOOR_ROW) * CELL_M
    entered_at: float | None = None
    now, north, backtrack, arrived = 0.0, y, 0.0, False
    for _ in range(max_actions):
        if entered_at is None and door_y - walker.y <= TRIGGER_M:
            entered_at = now
        true = world.copy()
        rows = person_rows(now - entered_at, stay_s) if entered_at is not None else None
        if rows is not None:
            true[max(1, rows[0]) : rows[1], 28:33] = OCCUPIED
        cell = xy_to_cell(SHAPE, walker.x, walker.y, CELL_M)
        if not in_bounds(SHAPE, cell):
            break
        seen, values = sensor.sense(true, inflated.occupancy, cell, walker.heading)
        flipped, now_blocked = inflated.apply(seen, values)
        if flipped.size:
            planner.update(flipped, now_blocked)
        path = path_from(planner, inflated, cell)
        pose = Pose(x=walker.x, y=walker.y, heading=walker.heading, stamp=now)
        out = guide.guide(path, pose, SHAPE, now, blocked=inflated.blocked)
        if out.pattern.kind is PatternKind.ARRIVED:
            arrived = True
            break
        walker.react(out.pattern, true)
        north = max(north, walker.y)
        backtrack = max(backtrack, north - walker.y)
        now += STEP_S
    return CrossingResult(
        arrived=arrived,
        walked_m=walker.walked_m,
        time_s=now,
        holds=policy.holds,
        backtrack_m=backtrack,
        collisions=walker.collisions,
    )
