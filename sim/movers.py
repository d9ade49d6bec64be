"""People who wander a room at walking speed, for Hong & DeSouza's moving-obstacle trials.

The paper (§V-A) let up to 10 simulated robots wander at random in the room its wheelchair
crossed; the laser saw them and they went into the grid as squares. Here each mover is a
person 0.4 m across (a disc of cells) walking at 1.0–1.4 m/s (drawn per person) straight to a
random point of the room, then to another, seeded. The ``Mover`` callback of
``closed_loop.run_walk`` rewrites the world's true map every action: the room's walls, then
every person where they now are. The sensor (3 m, 80°) reports what it sees, so a cell a
person has left becomes free in the known map as soon as the sensor looks at it again, and
one it does not look at stays occupied until it does: no ghost obstacle outlives a look.

People keep clear of the walker: a person whose next position would come within
``CLEAR_M`` of the walker stops this tick and picks another point (people step round a
pedestrian; the collisions counted are the walker's own steps into a person, what guidance
controls).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from daemon.planning.grid import FREE, OCCUPIED, UNKNOWN, cell_to_xy

from .courtyard import Scenario
from .world import World

CELL_M = 0.10
ROOM_SHAPE = (60, 60)
"""A 6 m x 6 m room (0.1 m cells) inside its walls."""
START = (45, 15)
GOAL = (27, 28)
"""2.2 m apart in a straight line, as the paper's 2.21 m crossing."""
PERSON_M = 0.4
SPEED_MPS = (1.0, 1.4)
CLEAR_M = 0.7
"""No person comes closer than this to the walker (centre to centre)."""


def room_world() -> np.ndarray:
    occ = np.full(ROOM_SHAPE, FREE, dtype=np.uint8)
    occ[0, :] = occ[-1, :] = occ[:, 0] = occ[:, -1] = OCCUPIED
    return occ


def room_scenario() -> Scenario:
    """The room as a walk: walls known, the inside unknown; 0.3 m radius, 3 m sensor."""
    true = room_world()
    known = np.where(true == OCCUPIED, OCCUPIED, UNKNOWN).astype(np.uint8)
    return Scenario(
        known=known, true=true, start=START, goal=GOAL, cell_m=CELL_M, radius_cells=3,
        sensor_range_cells=3.0 / CELL_M, unknown=0.0, coverage=0.0, seed=0, name="room",
    )  # fmt: skip


@dataclass
class Person:
    x: float
    y: float
    speed: float
    tx: float
    ty: float


class Movers:
    """The ``Mover``: ``count`` people, seeded, kept clear of the start, goal and walker."""

    def __init__(self, base: np.ndarray, count: int, seed: int) -> None:
        self.base = base
        self.rng = np.random.default_rng(seed)
        h, w = base.shape
        self.size_m = (w * CELL_M, h * CELL_M)
        ends = [cell_to_xy(base.shape, c, CELL_M) for c in (START, GOAL)]
        self.people: list[Person] = []
        while len(self.people) < count:
            x, y = self._point()
            if all(math.hypot(x - ex, y - ey) > 1.0 for ex, ey in ends):
                tx, ty = self._point()
                speed = float(self.rng.uniform(*SPEED_MPS))
                self.people.append(Person(x, y, speed, tx, ty))
        self.last_s = 0.0
        r = PERSON_M / CELL_M / 2
        k = math.ceil(r)
        dr, dc = np.mgrid[-k : k + 1, -k : k + 1]
        inside = (dr + 0.5) ** 2 + (dc + 0.5) ** 2 <= r * r + r
        self._dr, self._dc = dr[inside], dc[inside]

    def _point(self) -> tuple[float, float]:
        """A point of the room at least half a metre from its walls."""
        w, h = self.size_m
        return float(self.rng.uniform(0.6, w - 0.6)), float(self.rng.uniform(0.6, h - 0.6))

    def __call__(self, world: World, now: float) -> None:
        dt = now - self.last_s
        self.last_s = now
        wx, wy = world.walker.x, world.walker.y
        for p in self.people:
            step = p.speed * dt
            d = math.hypot(p.tx - p.x, p.ty - p.y)
            if d <= step:
                nx, ny = p.tx, p.ty
                p.tx, p.ty = self._point()
            else:
                nx, ny = p.x + (p.tx - p.x) * step / d, p.y + (p.ty - p.y) * step / d
            if math.hypot(nx - wx, ny - wy) < CLEAR_M:
                p.tx, p.ty = self._point()  # stop short of the walker, head elsewhere
                continue
            p.x, p.y = nx, ny
        self.paint(world.true)

    def paint(self, true: np.ndarray) -> None:
        true[:] = self.base
        h, w = true.shape
        for p in self.people:
            r0 = h - 1 - math.floor(p.y / CELL_M)
            c0 = math.floor(p.x / CELL_M)
            rr, cc = self._dr + r0, self._dc + c0
            keep = (rr >= 0) & (rr < h) & (cc >= 0) & (cc < w)
            true[rr[keep], cc[keep]] = OCCUPIED


@dataclass(frozen=True)
class TrialResult:
    arrived: bool
    collisions: int
    time_s: float
    walked_m: float
    interruptions: int
    """Steps whose route left the route the walker was guided on (``route_departs``)."""
    holds: int

    @property
    def success(self) -> bool:
        return self.arrived and self.collisions == 0


def crossing_trial(planner: str, movers: int, seed: int, backend: str = "cpu",
                   max_actions: int = 300) -> TrialResult:  # fmt: skip
    """One crossing of the room by a belt walker while ``movers`` people wander (seeded)."""
    from daemon.navigation import Navigator

    from .belt_walker import BeltWalker, WalkerParams
    from .closed_loop import STEP_S, run_walk
    from .walks import belt_settings

    scenario = room_scenario()
    crowd = Movers(scenario.true, movers, seed)
    crowd.paint(scenario.true)
    x, y = cell_to_xy(ROOM_SHAPE, START, CELL_M)
    walker = BeltWalker(x=x, y=y, heading=math.pi / 2, cell_m=CELL_M, params=WalkerParams(),
                        rng=np.random.default_rng(seed))  # fmt: skip
    world = World(scenario, walker)
    nav = Navigator("walker", belt_settings(scenario, backend, planner=planner))
    done = run_walk(world, nav, max_actions=max_actions, step_s=STEP_S, mover=crowd,
                    stop_on_no_path=False)  # fmt: skip
    return TrialResult(
        arrived=done.arrived,
        collisions=walker.collisions,
        time_s=(len(done.reports) - 1) * STEP_S,
        walked_m=walker.walked_m,
        interruptions=done.route_changes,
        holds=nav.guidance.hold.holds,
    )


def trials_row(planner: str, movers: int, trials: int, first_seed: int = 0,
               backend: str = "cpu") -> dict:  # fmt: skip
    """``trials`` seeded crossings summarised as the paper reports them (means over arrivals
    for time and length, over all trials for interruptions)."""
    done = [crossing_trial(planner, movers, first_seed + i, backend) for i in range(trials)]
    ok = [t for t in done if t.arrived]

    def mean(values: list[float]) -> float | None:
        return round(float(np.mean(values)), 2) if values else None

    return {
        "planner": planner, "movers": movers, "trials": trials, "backend": backend,
        "success_rate": sum(t.success for t in done) / trials,
        "arrived": len(ok), "collisions": sum(t.collisions for t in done),
        "walks_with_collision": sum(t.collisions > 0 for t in done),
        "time_s": mean([t.time_s for t in ok]), "length_m": mean([t.walked_m for t in ok]),
        "interruptions": mean([t.interruptions for t in done]),
        "holds": sum(t.holds for t in done),
    }  # fmt: skip
