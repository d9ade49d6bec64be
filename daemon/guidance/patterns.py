"""Belt patterns for four motors (front, right, back, left): what the user feels.

- GUIDE: the direction to the next turning point, a linear blend of the two nearest motors
  (decode: ``q = i + m[i+1] / (m[i] + m[i+1])`` quarter turns clockwise from the front), steady
  while the way is clear, pulsing faster as an obstacle ahead comes closer.
- Every event has its own shape, chosen so no two can be confused by touch (PATTERNS.md).
- Every pattern carries a time-to-live: the belt goes quiet by itself when the daemon stops.
- Hysteresis: near a motor's axis the belt snaps to that motor alone (Schmitt trigger, enter
  and leave at different angles), and small direction changes are ignored, so a user walking
  straight does not feel a second motor flicker from side to side.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

from protocol.messages import BeltPattern, PatternKind

QUARTER = math.pi / 2.0
GUIDE_INTENSITY = 200
"""Total GUIDE intensity shared by the two blended motors; events use up to 255."""
GUIDE_TTL_MS = 700
"""Longer than two pose periods at 5 Hz, short enough that a dead daemon is felt at once."""


@dataclass(frozen=True)
class EventShape:
    motors: tuple[int, int, int, int]
    period_ms: int
    ttl_ms: int


# front, right, back, left. GUIDE never drives two opposite motors and never pulses slower
# than PULSE_SLOW_MS, so each event below is unmistakable by touch alone.
EVENT_SHAPES: dict[PatternKind, EventShape] = {
    PatternKind.STOP: EventShape((255, 255, 255, 255), 0, 1500),
    PatternKind.ARRIVED: EventShape((200, 200, 200, 200), 1000, 3000),
    PatternKind.REROUTE: EventShape((0, 220, 0, 220), 400, 1200),
    PatternKind.NO_PATH: EventShape((255, 0, 255, 0), 250, 2000),
    PatternKind.WAIT: EventShape((140, 0, 140, 0), 1500, 1600),
    PatternKind.OFF: EventShape((0, 0, 0, 0), 0, 50),
    # The belt buttons (issue 26). PAUSED: one short tap on the back alone, which nothing
    # else drives (GUIDE behind becomes TURN_AROUND, back and a side), then quiet: over
    # within PAUSE_QUIET_MS of the press reaching the daemon. RESUMED: three motors (no other
    # pattern drives exactly three) for a moment, then GUIDE takes over.
    PatternKind.PAUSED: EventShape((0, 0, 255, 0), 0, 100),
    PatternKind.RESUMED: EventShape((0, 200, 200, 200), 0, 150),
    # Seed 004's "turn and look": no goal and the camera does not see the target. The front
    # and both sides (the half of the belt the user turns through), slow: no other pattern
    # drives these three, and RESUMED's three are a 150 ms tap, not a pulse.
    PatternKind.LOOK: EventShape((180, 180, 0, 180), 1000, 2100),
}
OBSTACLE_PULSE_MS = 120
"""OBSTACLE's pulse: faster than GUIDE's fastest (200 ms), so the two never feel alike."""
PAUSE_QUIET_MS = 200
"""After a pause the belt is quiet within this long (the PAUSED tap's TTL is shorter)."""

PULSE_NEAR_M = 1.0
"""Clearance below which GUIDE starts to pulse."""
PULSE_SLOW_MS, PULSE_FAST_MS = 800, 200
PULSE_MIN_M = 0.2


def pulse_period_ms(clearance_m: float | None) -> int:
    """Obstacle proximity → pulse period: steady (0) when clear, 800 ms at 1 m to 200 ms."""
    if clearance_m is None or clearance_m >= PULSE_NEAR_M:
        return 0
    f = (max(clearance_m, PULSE_MIN_M) - PULSE_MIN_M) / (PULSE_NEAR_M - PULSE_MIN_M)
    return round(PULSE_FAST_MS + f * (PULSE_SLOW_MS - PULSE_FAST_MS))


def blend(cw: float, intensity: int = GUIDE_INTENSITY) -> tuple[int, int, int, int]:
    """Direction ``cw`` (radians clockwise from the front) → intensities of the 2 nearest motors."""
    q = (cw % (2.0 * math.pi)) / QUARTER
    i = math.floor(q) % 4
    f = q - math.floor(q)
    out = [0, 0, 0, 0]
    hi = round(intensity * (1.0 - f))
    out[i] = hi
    out[(i + 1) % 4] = intensity - hi
    return (out[0], out[1], out[2], out[3])


def decode(motors: tuple[int, int, int, int]) -> float | None:
    """The direction a GUIDE pattern points to (radians clockwise from the front), or None.

    The inverse of ``blend``: the strongest motor and its stronger neighbour.
    """
    total = sum(motors)
    if total == 0:
        return None
    i = max(range(4), key=lambda k: motors[k])
    left_n, right_n = motors[(i - 1) % 4], motors[(i + 1) % 4]
    if right_n >= left_n:
        q = i + right_n / (motors[i] + right_n)
    else:
        q = i - left_n / (motors[i] + left_n)
    return (q * QUARTER) % (2.0 * math.pi)


def angle_diff(a: float, b: float) -> float:
    """Smallest signed difference a − b in (−π, π]."""
    d = (a - b + math.pi) % (2.0 * math.pi) - math.pi
    return math.pi if d == -math.pi else d


class DirectionHysteresis:
    """Filters the GUIDE direction so the belt does not flicker.

    - Snap: within ``snap_enter`` of a motor axis only that motor runs; it stays snapped
      until the direction leaves ``snap_leave`` (> enter) of that axis.
    - Dead band: changes smaller than ``dead_band`` from the last direction felt are ignored.
    """

    def __init__(
        self,
        snap_enter_deg: float = 12.0,
        snap_leave_deg: float = 20.0,
        dead_band_deg: float = 6.0,
    ) -> None:
        if snap_leave_deg < snap_enter_deg:
            raise ValueError("snap_leave must be at least snap_enter")
        self.snap_enter = math.radians(snap_enter_deg)
        self.snap_leave = math.radians(snap_leave_deg)
        self.dead_band = math.radians(dead_band_deg)
        self.snapped: int | None = None
        self.last: float | None = None

    def reset(self) -> None:
        self.snapped = None
        self.last = None

    def __call__(self, cw: float) -> float:
        cw %= 2.0 * math.pi
        if self.snapped is not None:
            if abs(angle_diff(cw, self.snapped * QUARTER)) <= self.snap_leave:
                self.last = self.snapped * QUARTER
                return self.last
            self.snapped = None
        nearest = round(cw / QUARTER) % 4
        if abs(angle_diff(cw, nearest * QUARTER)) <= self.snap_enter:
            self.snapped = nearest
            self.last = nearest * QUARTER
            return self.last
        if self.last is not None and abs(angle_diff(cw, self.last)) < self.dead_band:
            return self.last
        self.last = cw
        return cw


class PatternMaker:
    """Builds numbered, time-stamped BeltPatterns; one per user."""

    def __init__(self) -> None:
        self.seq = 0
        self.map_seq: Callable[[], int] = lambda: -1
        """The map version a pattern built now names (``BeltPattern.map_seq``): the user's map
        as it stands (the navigator points it at its ``MapKeeper``), so a pattern names the map
        it was decided on, and whoever measures delta→belt (``sim.load``) needs nothing else."""

    def _next(self) -> int:
        self.seq = (self.seq + 1) % 2**32
        return self.seq

    def guide(self, cw: float, clearance_m: float | None, now: float) -> BeltPattern:
        return BeltPattern(
            seq=self._next(),
            map_seq=self.map_seq(),
            kind=PatternKind.GUIDE,
            motors=blend(cw),
            period_ms=pulse_period_ms(clearance_m),
            ttl_ms=GUIDE_TTL_MS,
            stamp=now,
        )

    def turn_around(self, cw: float, now: float) -> BeltPattern:
        """The back motor and the side to turn towards, both strong, pulsing."""
        # cw below 180° is behind on the right. Straight behind (±10°): right, a fixed rule the
        # user learns, so the belt does not swap sides while the target sits dead astern.
        off = angle_diff(cw, math.pi)
        side = 1 if off < 0 or abs(off) < math.radians(10) else 3
        motors = [0, 0, 255, 0]
        motors[side] = 255
        return BeltPattern(
            seq=self._next(),
            map_seq=self.map_seq(),
            kind=PatternKind.TURN_AROUND,
            motors=(motors[0], motors[1], motors[2], motors[3]),
            period_ms=300,
            ttl_ms=1000,
            stamp=now,
        )

    def obstacle(self, cw: float, distance_m: float, now: float) -> BeltPattern:
        """An obstacle near on side ``cw`` (clockwise from the front): its nearest motor alone,
        pulsing every 120 ms (faster than GUIDE ever does), stronger the closer it is."""
        motor = round((cw % (2.0 * math.pi)) / QUARTER) % 4
        strength = round(255 - 115 * min(1.0, max(0.0, distance_m)))  # 255 at 0 m, 140 at 1 m
        motors = [0, 0, 0, 0]
        motors[motor] = strength
        return BeltPattern(
            seq=self._next(),
            map_seq=self.map_seq(),
            kind=PatternKind.OBSTACLE,
            motors=(motors[0], motors[1], motors[2], motors[3]),
            period_ms=OBSTACLE_PULSE_MS,
            ttl_ms=400,
            stamp=now,
        )

    def event(self, kind: PatternKind, now: float) -> BeltPattern:
        if kind not in EVENT_SHAPES:
            raise ValueError(f"{kind} needs a direction; use guide() or turn_around()")
        shape = EVENT_SHAPES[kind]
        return BeltPattern(
            seq=self._next(),
            map_seq=self.map_seq(),
            kind=kind,
            motors=shape.motors,
            period_ms=shape.period_ms,
            ttl_ms=shape.ttl_ms,
            stamp=now,
        )
