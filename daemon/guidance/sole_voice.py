"""When the voice is the user's only guide: say the way often enough, and stop before contact.

Beside a belt the voice is a companion: it names each new leg and keeps quiet, because the belt
corrects the heading every step (``cues.py``'s rate limits suit that). A person guided by voice
alone hears a direction, turns by it as well as a person can without sight, and walks straight
on until told something else; nothing corrects a heading 30° off, nothing says the way again to
someone who stopped. ``SoleVoice`` decides, at every guidance call, whether to speak:

1. **Stop before contact.** A user who is walking or turning (moved or turned since the last
   call) would cross a
   known obstacle with the next step along the heading (``ahead_m``, and two lines
   ``spread_deg`` either side for the veer of a step): "stop" now, a safety cue. The user's map
   is the daemon's: an obstacle not seen yet cannot be warned of. Someone standing is told the
   way instead, not "stop" again.
2. **The way after every stop or safety cue**, as soon as the safety cue has been said (the
   limiter's gap), even in the same words as before: they matter again.
3. **A new leg** (the target moved ≥ ``new_leg_m``) or **off course** (the target more than
   ``off_course_deg`` from the heading): the way, with the new clock hour.
4. **No progress** (moved under ``stall_m`` in ``stall_s`` while being guided): the way again.
5. **Reassurance** every ``reassure_s`` on a leg: the way again, with the distance left.

Every direction goes through the ``CueLimiter`` the caller configured (``sole_limiter``), so
cues never pile up: one at least ``min_gap_s`` after the last, whatever rule asked for it.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from daemon.planning.grid import OCCUPIED
from protocol.messages import PatternKind, VoiceCue

from .cues import CueLimiter, CueMaker, clock_hour
from .turning_points import relative_angle

MOVED_M = 0.05
"""Less than this between two calls is standing (a pose's own jitter)."""
FAN_STEP_DEG = 5.0
TURNED_DEG = 10.0
"""More than this between two calls is turning on the spot."""


@dataclass(frozen=True)
class SoleVoiceSettings:
    ahead_m: float = 0.65
    """How far ahead a step may not cross an obstacle: a step (0.5 m) and the distance walked
    while "stop" is said."""
    spread_deg: float = 10.0
    step_m: float = 0.5
    """A walking step: where the next one ends."""
    turn_error_deg: float = 60.0
    """How far a person turning by ear to a clock hour may miss it."""
    new_leg_m: float = 1.0
    off_course_deg: float = 20.0
    """Beyond the ±15° that "12 o'clock" covers, with a margin so a cue is not repeated for
    a heading on the edge of the hour."""
    stall_m: float = 0.15
    stall_s: float = 2.5
    reassure_s: float = 6.0
    min_gap_s: float = 1.5
    """About the time a direction takes to say."""


def hour_angle(hour: int) -> float:
    """A clock hour as a clockwise angle from straight ahead, radians in (−π, π]."""
    a = math.radians(30.0 * (hour % 12))
    return a - 2 * math.pi if a > math.pi else a


def crosses_occupied(occupancy: np.ndarray, a: np.ndarray, b: np.ndarray) -> bool:
    """True when the segment a → b (continuous cell units) passes through an OCCUPIED cell or
    leaves the map; sampled every tenth of a cell, as the walk's collisions are counted."""
    h, w = occupancy.shape
    n = max(1, math.ceil(float(np.hypot(*(b - a))) * 10.0))
    t = np.linspace(0.0, 1.0, n + 1)[1:]  # the user's own cell is where it already stands
    rows = np.floor(a[0] + t * (b[0] - a[0])).astype(np.int64)
    cols = np.floor(a[1] + t * (b[1] - a[1])).astype(np.int64)
    if rows.min() < 0 or rows.max() >= h or cols.min() < 0 or cols.max() >= w:
        return True
    return bool(np.any(occupancy[rows, cols] == OCCUPIED))


def sole_limiter(settings: SoleVoiceSettings | None = None) -> CueLimiter:
    """Rate limits for a voice that guides alone: a cue may follow the last once it has been
    said, the same words may be said again (a correction often repeats them), and "stop" may
    be said again after a second (a user who walks on after one needs another)."""
    s = settings or SoleVoiceSettings()
    return CueLimiter(min_interval_s=s.min_gap_s, repeat_s=0.0, safety_dedupe_s=1.0)


class SoleVoice:
    """The rules above, with the state they need between calls."""

    def __init__(self, cues: CueMaker, settings: SoleVoiceSettings | None = None) -> None:
        self.cues = cues
        self.s = settings or SoleVoiceSettings()
        self.stops = 0
        """Stops said before contact."""
        self.reset()

    def reset(self) -> None:
        self._owed = True  # the way is owed: at the start, after a stop or a safety cue
        self._target: np.ndarray | None = None
        self._said_at = -math.inf
        self._anchor: tuple[np.ndarray, float] | None = None  # where the user was, when
        self._last_user: tuple[np.ndarray, float] | None = None

    def after_safety(self) -> None:
        """A safety cue was said (stop, wait, reroute, turn around…): the way is owed."""
        self._owed = True

    def said_way(self, target: np.ndarray, now: float) -> None:
        """The way was said by another rule (a new route announced with its direction)."""
        self._owed = False
        self._target = target.copy()
        self._said_at = now

    def stop_before_contact(
        self,
        occupancy: np.ndarray | None,
        blocked: np.ndarray | None,
        user: np.ndarray,
        heading: float,
        cell_m: float,
        now: float,
    ) -> tuple[bool, VoiceCue | None]:
        """Rule 1: whether the next step would cross a known obstacle, and the "stop" to say
        (None when the limiter held it back: said less than a second ago)."""
        last, self._last_user = self._last_user, (user.copy(), heading)
        moving = last is not None and (
            float(np.hypot(*(user - last[0]))) * cell_m > MOVED_M
            or abs(relative_angle(heading, last[1])) > math.radians(TURNED_DEG)
        )
        if occupancy is None or not moving:
            # Someone standing still is not about to walk into anything: they wait for the
            # way. Someone who just turned on the spot is: they walk next.
            return False, None
        if self._clear(occupancy, user, heading, math.radians(self.s.spread_deg), cell_m) and not (
            self._into_margin(blocked, user, heading, cell_m)
        ):
            return False, None
        cue = self.cues.event(PatternKind.STOP, now)
        self._owed = True
        if cue is not None:
            self.stops += 1
        return True, cue

    def _into_margin(
        self, blocked: np.ndarray | None, user: np.ndarray, heading: float, cell_m: float
    ) -> bool:
        """From free space, a step along ``heading`` would end inside the inflation margin:
        off the route, towards obstacles or into a pocket the route cannot leave from."""
        if blocked is None:
            return False
        h, w = blocked.shape
        r, c = int(user[0]), int(user[1])
        if not (0 <= r < h and 0 <= c < w) or blocked[r, c]:
            return False  # already inside: the route leads out, let it
        end = user + (self.s.step_m / cell_m) * np.array([-math.sin(heading), math.cos(heading)])
        re, ce = int(end[0]), int(end[1])
        return not (0 <= re < h and 0 <= ce < w) or bool(blocked[re, ce])

    def _clear(
        self, occupancy: np.ndarray, user: np.ndarray, heading: float, spread: float, cell_m: float
    ) -> bool:
        """No known obstacle within ``ahead_m`` in the fan of headings ``spread`` either side
        (lines every ``FAN_STEP_DEG`` at most: an obstacle cell between two lines of a wide
        fan would otherwise be missed)."""
        reach = self.s.ahead_m / cell_m
        n = max(1, math.ceil(spread / math.radians(FAN_STEP_DEG)))
        for a in heading + np.linspace(-spread, spread, 2 * n + 1):
            if crosses_occupied(
                occupancy, user, user + reach * np.array([-math.sin(a), math.cos(a)])
            ):
                return False
        return True

    def _safest_hour(
        self, occupancy: np.ndarray | None, user: np.ndarray, heading: float, rel: float,
        cell_m: float,
    ) -> tuple[float, bool]:  # fmt: skip
        """The relative angle to say, and whether to turn on the spot and wait: the clock hour
        of ``rel``, or the hour beside it, when a person turning to it by ear (±
        ``turn_error_deg``) and walking on could not step into a known obstacle; when neither
        is clear, the hour of ``rel`` with "and wait" — the user turns, the next call sees
        the heading they took and says the way from there. "12 o'clock" asks for no turn, so
        only the veer of a step is allowed for it."""
        hour = clock_hour(rel)
        if occupancy is None:
            return rel, False
        # The neighbouring hour on the target's side of this one first.
        side = 1 if -rel > hour_angle(hour) else -1
        for h in (hour, (hour - 1 + side) % 12 + 1, (hour - 1 - side) % 12 + 1):
            turn = -hour_angle(h)
            spread = self.s.spread_deg if h == 12 else self.s.turn_error_deg
            if self._clear(occupancy, user, heading + turn, math.radians(spread), cell_m):
                return (rel if h == hour else turn), False
        if hour == 12:  # no turn is safe to walk on from: turn a little, on the spot
            return -hour_angle(1 if rel <= 0 else 11), True
        return rel, True

    def way(
        self, target: np.ndarray, user: np.ndarray, rel: float, metres: float, cell_m: float,
        now: float, occupancy: np.ndarray | None = None, heading: float = 0.0,
    ) -> VoiceCue | None:  # fmt: skip
        """Rules 2–5: the direction to ``target`` when one of them asks for it and the limiter
        lets it through; else None."""
        if self._anchor is None or float(np.hypot(*(user - self._anchor[0]))) * cell_m >= (
            self.s.stall_m
        ):
            self._anchor = (user.copy(), now)
        new_leg = self._target is None or (
            float(np.hypot(*(target - self._target))) * cell_m >= self.s.new_leg_m
        )
        off_course = abs(rel) > math.radians(self.s.off_course_deg)
        stalled = now - self._anchor[1] >= self.s.stall_s and now - self._said_at >= self.s.stall_s
        reassure = now - self._said_at >= self.s.reassure_s
        if not (self._owed or new_leg or off_course or stalled or reassure):
            return None
        say, wait = self._safest_hour(occupancy, user, heading, rel, cell_m)
        cue = self.cues.direction(say, metres, now, wait)
        if cue is not None:
            self._owed = wait  # after turning on the spot the user waits for the way
            self._target = target.copy()
            self._said_at = now
        return cue
