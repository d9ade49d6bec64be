"""A person steps into the doorway ahead: hold instead of detour, shown.

The user walks north up a corridor (walls 2 m apart, open at the south end) towards a door
5 m ahead, the goal beyond it. When the user is 2.5 m from the door a person walks into the
doorway from the north, stands in it for ``stay_s`` and walks away north again. The only other
way to the goal is back out of the corridor's south end and round the outside: a planner that
replans on what it sees turns the user around, as Hong & DeSouza's wheelchair did. With the
hold, guidance says "wait" and the user stands until the doorway clears.

The loop is ``closed_loop.run_walk`` (the daemon's ``Navigator`` guiding a belt walker) with a
``Mover`` that puts the person into the world's true map as time goes on; the hold policy is
the navigator's guidance's.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from daemon.planning.grid import FREE, OCCUPIED, UNKNOWN, cell_to_xy

from .belt_walker import BeltWalker, WalkerParams
from .closed_loop import STEP_S, run_walk
from .courtyard import Scenario
from .world import World

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


def corridor_scenario() -> Scenario:
    """The corridor as a walk: walls known, the rest unknown; 0.3 m radius, 3 m sensor."""
    true = corridor_world()
    known = np.where(true == OCCUPIED, OCCUPIED, UNKNOWN).astype(np.uint8)
    return Scenario(
        known=known, true=true, start=START, goal=GOAL, cell_m=CELL_M, radius_cells=3,
        sensor_range_cells=3.0 / CELL_M, unknown=0.0, coverage=0.0, seed=0,
    )  # fmt: skip


class DoorwayPerson:
    """The ``Mover``: the person enters the doorway once the user is ``TRIGGER_M`` from it."""

    def __init__(self, base: np.ndarray, stay_s: float) -> None:
        self.base = base
        self.stay_s = stay_s
        self.entered_at: float | None = None
        self.door_y = (SHAPE[0] - DOOR_ROW) * CELL_M

    def __call__(self, world: World, now: float) -> None:
        if self.entered_at is None and self.door_y - world.walker.y <= TRIGGER_M:
            self.entered_at = now
        world.true[:] = self.base
        if self.entered_at is None:
            return
        rows = person_rows(now - self.entered_at, self.stay_s)
        if rows is not None:
            world.true[max(1, rows[0]) : rows[1], 28:33] = OCCUPIED


def crossing_walk(
    hold: bool = True, stay_s: float = 3.0, seed: int = 0, max_actions: int = 600
) -> CrossingResult:
    from daemon.guidance.guide import Guidance
    from daemon.guidance.hold import HoldPolicy
    from daemon.navigation import Navigator

    from .walks import belt_settings

    scenario = corridor_scenario()
    settings = belt_settings(scenario)
    # hold_s=0: the policy is there but never waits, so the planner's detour is taken at once.
    policy = HoldPolicy() if hold else HoldPolicy(hold_s=0.0)
    guide = Guidance(cell_m=CELL_M, radius_m=settings.user_radius_m, arrive_m=settings.arrive_m,
                     hold=policy)  # fmt: skip
    x, y = cell_to_xy(SHAPE, START, CELL_M)
    walker = BeltWalker(x=x, y=y, heading=math.pi / 2, cell_m=CELL_M,
                        params=WalkerParams(), rng=np.random.default_rng(seed))  # fmt: skip
    world = World(scenario, walker)
    done = run_walk(world, Navigator("walker", settings, guidance=guide), max_actions=max_actions,
                    step_s=STEP_S, mover=DoorwayPerson(scenario.true, stay_s),
                    stop_on_no_path=False)  # fmt: skip
    ys = np.array([p[1] for p in done.track])
    return CrossingResult(
        arrived=done.arrived,
        walked_m=walker.walked_m,
        # The clock of the last navigator step: the arrival's, as the old loop counted it.
        time_s=(len(done.reports) - 1) * STEP_S,
        holds=policy.holds,
        backtrack_m=float((np.maximum.accumulate(ys) - ys).max()),
        collisions=walker.collisions,
    )
