"""The simulated user who walks by feel: reads the belt, never the path.

Each step the walker takes the latest BeltPattern (any object with ``kind``, ``motors`` and
``period_ms``) and reacts as a person wearing the belt would:

- GUIDE: decode the felt direction from the two strongest neighbouring motors, with a
  perception error; a direction far off the nose is first turned to on the spot, otherwise
  the walker turns and steps, with a gait error on the step's direction and a step length
  drawn around a cautious walking pace; while the belt pulses (an obstacle is near) the steps
  are shorter, the faster the pulse the shorter (a quarter at the fastest).
- TURN_AROUND: turn on the spot towards the felt side (back and one side motor), about 180°.
- LOOK ("turn and look"): turn on the spot, clockwise, by ``look_turn_deg`` a step.
- STOP, WAIT, NO_PATH, REROUTE, ARRIVED, OFF: stand still.

Steps happen in continuous metres (x east, y north, origin at the map's south-west corner).
A step whose straight line would enter an OCCUPIED cell of the true map is a collision: it is
counted and the walker stays where it was, as a person stops on bumping into something.

Imports numpy only (the GPU machine runs the sim without pydantic).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np

OCCUPIED = 1
QUARTER = math.pi / 2.0


@dataclass(frozen=True)
class WalkerParams:
    """A cautious adult walking with a guidance belt (defaults documented in PATTERNS.md)."""

    step_m: float = 0.5
    step_sd_m: float = 0.05
    slow_factor: float = 0.25
    """Step length multiplier at the fastest pulse (obstacle touching the margin); it rises
    in proportion to the pulse period up to 1 at 800 ms (1 m clear)."""
    perception_sd_deg: float = 8.0
    """Error in reading a direction off a four-motor belt."""
    gait_sd_deg: float = 4.0
    """Veer of each step away from the intended direction."""
    turn_in_place_deg: float = 40.0
    """Directions further off than this are turned to on the spot before stepping: half the
    sensor's 80° field of view, so a step never goes where the sensor has not just looked."""
    look_turn_deg: float = 45.0
    """A slow turn on LOOK: about half a camera's view per step, so nothing is skipped."""


def felt_direction(motors: tuple[int, int, int, int] | list[int]) -> float | None:
    """Radians clockwise from the front that the motors point to, or None when all are off.

    The strongest motor and its stronger neighbour share the quarter turn between them in
    proportion to their intensities: the belt's documented blend (PATTERNS.md).
    """
    m = [int(v) for v in motors]
    if sum(m) == 0:
        return None
    i = max(range(4), key=lambda k: m[k])
    left_n, right_n = m[(i - 1) % 4], m[(i + 1) % 4]
    if right_n >= left_n:
        q = i + (right_n / (m[i] + right_n) if right_n else 0.0)
    else:
        q = i - left_n / (m[i] + left_n)
    return (q * QUARTER) % (2.0 * math.pi)


def step_hits(
    occupancy: np.ndarray, cell_m: float, x0: float, y0: float, x1: float, y1: float
) -> bool:
    """True when the straight step (x0, y0) → (x1, y1) passes through an OCCUPIED cell.

    Samples the segment every tenth of a cell, ends included; leaving the map is a hit.
    """
    return first_hit(occupancy, cell_m, x0, y0, x1, y1) is not None


def first_hit(
    occupancy: np.ndarray, cell_m: float, x0: float, y0: float, x1: float, y1: float
) -> tuple[int, int] | None:
    """The first OCCUPIED cell (row, col) the step (x0, y0) → (x1, y1) runs into, sampled
    as ``step_hits`` does; ``(-1, -1)`` when the step leaves the map; None when it is free."""
    h, w = occupancy.shape
    n = max(1, math.ceil(math.hypot(x1 - x0, y1 - y0) / (0.1 * cell_m)))
    t = np.linspace(0.0, 1.0, n + 1)
    xs = x0 + t * (x1 - x0)
    ys = y0 + t * (y1 - y0)
    rows = h - 1 - np.floor(ys / cell_m).astype(np.int64)
    cols = np.floor(xs / cell_m).astype(np.int64)
    inside = (rows >= 0) & (rows < h) & (cols >= 0) & (cols < w)
    blocked = ~inside
    blocked[inside] = occupancy[rows[inside], cols[inside]] == OCCUPIED
    hit = np.flatnonzero(blocked)
    if hit.size == 0:
        return None
    i = hit[0]
    return (int(rows[i]), int(cols[i])) if inside[i] else (-1, -1)


@dataclass(frozen=True)
class Bump:
    """One collision, as the walker knows it: where it stood, where the step went, what it
    felt. The walk adds what only the world knows (what the cell holds, how old the frame
    was: ``camera_node``)."""

    x: float
    y: float
    heading: float
    """Radians, counter-clockwise from east: the step's intended direction."""
    to_x: float
    to_y: float
    cell: tuple[int, int]
    """The first occupied cell on the step (``first_hit``)."""
    kind: str
    """The pattern felt: ``guide`` (a step) is the only kind that moves the walker."""
    motors: tuple[int, ...]
    period_ms: int


@dataclass
class BeltWalker:
    x: float
    y: float
    heading: float
    cell_m: float
    params: WalkerParams = field(default_factory=WalkerParams)
    rng: np.random.Generator = field(default_factory=lambda: np.random.default_rng(0))
    walked_m: float = 0.0
    steps: int = 0
    turns: int = 0
    collisions: int = 0
    bumps: list[Bump] = field(default_factory=list)

    def act(self, view: Any) -> str:
        """The world's walker seam (``world.py``): only ``view.belt`` and the true map are
        used — never ``view.path``. A pattern past its TTL is felt as nothing."""
        belt = view.belt
        if belt is None or view.now > belt.stamp + belt.ttl_ms / 1000.0:
            return "stand"
        return self.react(belt, view.true)

    def react(self, pattern: Any, occupancy: np.ndarray) -> str:
        """Feel ``pattern`` and act once: ``"step"``, ``"turn"``, ``"stand"`` or ``"bump"``."""
        kind = str(pattern.kind)
        if kind == "turn_around":
            felt = felt_direction(pattern.motors)
            side = -QUARTER if felt is not None and felt < math.pi else QUARTER  # right: cw
            turn = 2.0 * side + self._noise(self.params.perception_sd_deg)
            self.heading = _wrap(self.heading + turn)
            self.turns += 1
            return "turn"
        if kind == "look":
            turn = math.radians(self.params.look_turn_deg)
            self.heading = _wrap(self.heading - turn + self._noise(self.params.perception_sd_deg))
            self.turns += 1
            return "turn"
        if kind != "guide":
            return "stand"
        felt = felt_direction(pattern.motors)
        if felt is None:
            return "stand"
        rel = -felt + self._noise(self.params.perception_sd_deg)  # CCW-positive, user frame
        rel = _wrap(rel)
        self.heading = _wrap(self.heading + rel)
        if abs(rel) > math.radians(self.params.turn_in_place_deg):
            self.turns += 1
            return "turn"
        return self._step(int(pattern.period_ms), occupancy, pattern)

    def _step(self, period_ms: int, occupancy: np.ndarray, pattern: Any = None) -> str:
        p = self.params
        length = max(0.05, self.rng.normal(p.step_m, p.step_sd_m))
        if period_ms > 0:  # pulsing: an obstacle is near, shorter steps the faster it pulses
            length *= max(p.slow_factor, min(1.0, period_ms / 800.0))
        direction = self.heading + self._noise(p.gait_sd_deg)
        x1 = self.x + length * math.cos(direction)
        y1 = self.y + length * math.sin(direction)
        hit = first_hit(occupancy, self.cell_m, self.x, self.y, x1, y1)
        if hit is not None:
            self.collisions += 1
            kind = "guide" if pattern is None else str(pattern.kind)
            motors = () if pattern is None else tuple(int(m) for m in pattern.motors)
            self.bumps.append(Bump(self.x, self.y, direction, x1, y1, hit, kind, motors,
                                   period_ms))  # fmt: skip
            return "bump"
        self.x, self.y = x1, y1
        self.walked_m += length
        self.steps += 1
        return "step"

    def _noise(self, sd_deg: float) -> float:
        return math.radians(self.rng.normal(0.0, sd_deg)) if sd_deg > 0 else 0.0


def _wrap(a: float) -> float:
    return (a + math.pi) % (2.0 * math.pi) - math.pi


def belt_walker_for(scenario: Any, x: float, y: float, heading: float, seed: int = 0) -> BeltWalker:
    """Factory for the sim node's ``--follow belt`` (its ``WALKERS`` table)."""
    return BeltWalker(
        x=x, y=y, heading=heading, cell_m=scenario.cell_m, rng=np.random.default_rng(seed)
    )
