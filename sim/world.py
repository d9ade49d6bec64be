"""The simulated world of one user: the true map, what the sensor has told the map, a walker.

A ``World`` plays everything outside the navigator: the mapper (map deltas of what the sensor
sees from where the user stands), the localiser (the user's pose) and the person (a walker that
acts on the path or on the belt). The in-process loop (``closed_loop.py``) and the zenoh node
(``node.py``) drive the same world, so a walk is the same walk whichever way its messages go.

Walkers are pluggable: ``WALKERS`` maps a name (``--follow``) to a factory. ``path`` steps to
the next cell of the planned path; ``belt`` feels the pattern and never sees the path.
"""

from __future__ import annotations

import math
import secrets
from collections.abc import Callable
from dataclasses import dataclass
from typing import Protocol

import numpy as np

from daemon.planning.grid import OCCUPIED, Cell, cell_to_xy, xy_to_cell
from protocol.messages import (
    MAX_DELTA_CELLS,
    BeltPattern,
    MapDelta,
    MapSnapshot,
    Pose,
    VoiceCue,
)

from .belt_walker import belt_walker_for, step_hits
from .courtyard import Scenario
from .sensor import Sensor

LOOKAHEAD_M = 0.5
"""The path walker faces the path point this far ahead, so the sensor looks along the path."""


@dataclass
class WalkerView:
    """What a walker may use to act once."""

    path: np.ndarray | None
    """``(k, 2)`` cells planned from the user's current cell, or None."""
    belt: BeltPattern | None
    """The pattern the belt is showing now."""
    true: np.ndarray
    """The world's occupancy, to find out the hard way what a step runs into."""
    now: float
    """The world's clock (simulated or wall), for patterns that expire."""
    voice: tuple[VoiceCue, ...] = ()
    """The cues spoken during this step (usually none): a listener hears each once, when it is
    said, and never again; walkers that feel the belt ignore them."""


class Walker(Protocol):
    x: float
    y: float
    heading: float

    def act(self, view: WalkerView) -> str:
        """Act once: ``"step"``, ``"turn"``, ``"stand"`` or ``"bump"`` (a collision)."""
        ...


def heading_along(path: np.ndarray, lookahead: int, fallback: float) -> float:
    """Bearing (0 = east, counter-clockwise) from ``path[0]`` to the point ``lookahead`` on."""
    if len(path) < 2:
        return fallback
    r0, c0 = path[0]
    r1, c1 = path[min(lookahead, len(path) - 1)]
    return math.atan2(-(int(r1) - int(r0)), int(c1) - int(c0))


@dataclass
class PathWalker:
    """Steps to the centre of the next cell of the path, facing half a metre ahead on it."""

    x: float
    y: float
    heading: float
    cell_m: float
    collisions: int = 0

    def act(self, view: WalkerView) -> str:
        path = view.path
        if path is None or len(path) < 2:
            return "stand"
        shape = view.true.shape
        x1, y1 = cell_to_xy(shape, (int(path[1][0]), int(path[1][1])), self.cell_m)
        lookahead = max(1, round(LOOKAHEAD_M / self.cell_m))
        if step_hits(view.true, self.cell_m, self.x, self.y, x1, y1):
            self.collisions += 1
            return "bump"
        self.x, self.y = x1, y1
        self.heading = heading_along(path[1:], lookahead, self.heading)
        return "step"


def _path_walker(scenario: Scenario, x: float, y: float, heading: float, seed: int) -> Walker:
    del seed  # the path walker has no noise
    return PathWalker(x, y, heading, scenario.cell_m)


WALKERS: dict[str, Callable[[Scenario, float, float, float, int], Walker]] = {
    "path": _path_walker,
    "belt": belt_walker_for,
}
"""``--follow`` name → factory ``(scenario, x, y, heading, seed) -> Walker``."""


class World:
    """One user in one world: sensing, poses and the walker's actions."""

    def __init__(
        self,
        scenario: Scenario,
        walker: str | Walker = "path",
        *,
        seed: int = 0,
        start: Cell | None = None,
        heading: float = math.pi / 2,
        fov_deg: float = 80.0,
        epoch: int | None = None,
    ) -> None:
        """``epoch``: the map source's (random when None, as a real mapper picks one)."""
        self.scenario = scenario
        self.shape = scenario.shape
        self.cell_m = scenario.cell_m
        self.true = scenario.true.copy()
        """What is really there; a world with movers changes it as time goes on."""
        self.known = scenario.known.copy()
        """What the map producer has published so far."""
        self.sensor = Sensor(scenario.sensor_range_cells, fov_deg)
        self.seq = -1
        self.epoch = secrets.randbits(64) if epoch is None else epoch
        if isinstance(walker, str):
            x, y = cell_to_xy(self.shape, start or scenario.start, self.cell_m)
            walker = WALKERS[walker](scenario, x, y, heading, seed)
        self.walker = walker

    def cell(self) -> Cell:
        return xy_to_cell(self.shape, self.walker.x, self.walker.y, self.cell_m)

    def first_deltas(self, stamp: float) -> list[MapDelta]:
        """Delta 0 with the known obstacles when they fit in one (else the navigator, seeing
        delta 1 first, asks for a snapshot), then what the sensor sees from the start."""
        out = []
        occupied = np.flatnonzero(self.known == OCCUPIED)
        if occupied.size <= MAX_DELTA_CELLS:
            out += self._deltas(occupied, np.full(occupied.size, OCCUPIED, np.uint8), stamp,
                                at_least_one=True)  # fmt: skip
        else:
            self.seq = 0
        return out + self.sense(stamp)

    def restart_mapper(self, stamp: float, epoch: int | None = None) -> list[MapDelta]:
        """The map source starts again: a new epoch, its deltas counted from 0 again, delta 0
        first as at the start. What it had published it still knows (a mapper that reloads
        its own map on start)."""
        self.epoch = secrets.randbits(64) if epoch is None else epoch
        self.seq = -1
        return self.first_deltas(stamp)

    def sense(self, stamp: float) -> list[MapDelta]:
        """The deltas of what the sensor sees now that the map does not know yet (none when
        nothing is new; several when a sweep changes more cells than one delta may carry)."""
        cells, values = self.sensor.sense(self.true, self.known, self.cell(), self.walker.heading)
        return self._deltas(cells, values, stamp)

    def snapshot(self, stamp: float) -> MapSnapshot:
        """Everything published so far in one message: the map producer's answer when the
        navigator has lost the sequence (or a first map too large for one delta)."""
        return MapSnapshot.from_array(max(self.seq, 0), self.known, stamp, self.epoch)

    def pose(self, stamp: float) -> Pose:
        return Pose(x=self.walker.x, y=self.walker.y, heading=self.walker.heading, stamp=stamp)

    def act(
        self,
        path: np.ndarray | None,
        belt: BeltPattern | None,
        now: float,
        voice: tuple[VoiceCue, ...] = (),
    ) -> str:
        return self.walker.act(WalkerView(path, belt, self.true, now, voice))

    def _deltas(
        self, cells: np.ndarray, values: np.ndarray, stamp: float, at_least_one: bool = False
    ) -> list[MapDelta]:
        """The change as deltas of at most ``MAX_DELTA_CELLS`` cells, in sequence."""
        self.known.reshape(-1)[cells] = values
        out = []
        for at in range(0, max(cells.size, int(at_least_one)), MAX_DELTA_CELLS):
            self.seq += 1
            part = slice(at, at + MAX_DELTA_CELLS)
            out.append(
                MapDelta.from_arrays(
                    self.seq, self.shape, cells[part], values[part], stamp, self.epoch
                )
            )
        return out
