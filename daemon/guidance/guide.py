"""Guidance for one user: path + pose → the belt pattern to feel and the cue to hear.

Composes the pieces top to bottom: arrival check → (optional rubber-band smoothing) →
turning points with any-angle shortcuts → heading to the next point relative to the user →
hold-instead-of-detour → turn around or GUIDE with hysteresis and obstacle pulse → a clock-face
cue, rate limited. ``event`` gives the fixed patterns (STOP, NO_PATH, …) with their cue.

One ``Guidance`` per user session; it keeps state (hysteresis, cue limiter, hold) between
calls, so call it for every new pose or path, in time order.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass
from typing import Literal

import numba
import numpy as np

from protocol.messages import BeltPattern, PatternKind, Pose, VoiceCue

from .clearance import forward_clearance_m
from .cues import SAFETY_KINDS, CueLimiter, CueMaker, Units, Wording, clock_hour
from .hold import HoldPolicy
from .patterns import DirectionHysteresis, PatternMaker
from .route_watch import RouteWatch
from .smoothing import planner_band, rubber_band
from .sole_voice import SoleVoice, SoleVoiceSettings, sole_limiter
from .turning_points import (
    KeptPoints,
    bearing,
    is_core,
    relative_angle,
    segment_clear,
    segment_free,
    xy_to_continuous,
)

REASSURE_MIN_M = 5.0
"""A leg at least this long is worth a reassurance ("straight ahead, 12 metres")."""
COUNTDOWN_M = (10.0, 5.0, 2.0)
"""Distances to the goal announced on the last leg ("goal in 5 metres")."""


@dataclass(frozen=True)
class GuidanceOutput:
    pattern: BeltPattern
    cue: VoiceCue | None
    target: tuple[float, float] | None = None
    """The turning point guided to, in metres (x, y); None for events. For viewers and tests."""


class Guidance:
    """Turns the planner's path into what one user feels and hears.

    ``radius_m`` must be the radius the ``blocked`` map was inflated by (the daemon's
    ``user_radius_m``): how much of the margin a line to the target may shave comes from it.
    """

    def __init__(
        self,
        *,
        cell_m: float = 0.10,
        lang: Literal["en", "es"] = "en",
        arrive_m: float = 0.3,
        reach_m: float = 0.35,
        escape_m: float = 0.25,
        radius_m: float = 0.30,
        max_leg_m: float = 8.0,
        turn_around_deg: float = 135.0,
        smooth: bool = False,
        hold: HoldPolicy | None = None,
        limiter: CueLimiter | None = None,
        voice: Literal["companion", "sole"] = "companion",
        sole: SoleVoiceSettings | None = None,
        wording: Wording = "clock",
        units: Units = "metric",
        reassure_s: float = 15.0,
    ) -> None:
        """``voice="sole"``: the voice is the user's only guide (no belt worn, or the user's
        choice): ``sole_voice.py`` decides when to speak, and says "stop" before contact."""
        self.cell_m = float(cell_m)
        self.arrive_m = arrive_m
        self.reach_m = reach_m
        self.escape_m = min(escape_m, 0.9 * radius_m)
        self.max_leg_cells = max_leg_m / cell_m
        self.turn_around = math.radians(turn_around_deg)
        self.smooth = smooth
        self.planner: Callable[[], object] | None = None
        """The planner whose path is guided (the navigator's route sets it): smoothing uses
        that planner's own model where it has one (``smoothing.planner_band``)."""
        self.hold = hold if hold is not None else HoldPolicy()
        self.patterns = PatternMaker()
        self.reassure_s = float(reassure_s)
        """Beside the belt, the way is said again this often on a long leg (0: never); a sole
        voice has its own, shorter interval (``sole_voice.py``)."""
        self._radius_m = radius_m
        self._sole_settings = sole
        self.cues = CueMaker(lang, limiter, wording, units)
        self.voice: Literal["companion", "sole"] = "companion"
        self.sole: SoleVoice | None = None
        self._set_voice(voice, limiter)
        self.hysteresis = DirectionHysteresis()
        self.route_watch = RouteWatch()
        self._announced: tuple[np.ndarray, int] | None = None
        self._announced_at = -math.inf
        self._countdown: set[float] = set()
        self._kept_points = KeptPoints()

    def _set_voice(self, voice: str, limiter: CueLimiter | None = None) -> None:
        if voice not in ("companion", "sole"):
            raise ValueError(f"voice must be companion or sole, got {voice!r}")
        self.voice = voice  # type: ignore[assignment]
        if voice == "sole":
            self.cues.limiter = limiter or sole_limiter(self._sole_settings)
            self.sole = SoleVoice(self.cues, self._sole_settings)
            # A listener turns by ear to ±tens of degrees: a line that shaves the margin
            # leaves it no room; lines to the target stay wholly outside it.
            self.shave_cells = 0
        else:
            self.cues.limiter = limiter or CueLimiter()
            self.sole = None
            # Half the user's radius of the margin may be shaved by a line from the user.
            self.shave_cells = int(0.5 * self._radius_m / self.cell_m)

    def apply(
        self, voice: str | None = None, wording: str | None = None, units: str | None = None
    ) -> None:
        """A user's settings changed while walking (None: as it was). A new voice role starts
        with a fresh limiter and says the way at once."""
        if wording is not None:
            self.cues.wording = wording  # type: ignore[assignment]
        if units is not None:
            self.cues.units = units  # type: ignore[assignment]
        if voice is not None and voice != self.voice:
            self._set_voice(voice)
            self._announced = None

    @property
    def lang(self) -> str:
        return self.cues.lang

    def reset(self) -> None:
        """A new goal: forget arrival, hysteresis, holds and what was said."""
        self.hysteresis.reset()
        self.hold.reset()
        self.cues.limiter.reset()
        self._announced = None
        self.route_watch.reset()
        self._countdown.clear()
        if self.sole is not None:
            self.sole.reset()

    def event(self, kind: PatternKind, now: float, reason: str = "") -> GuidanceOutput:
        """A fixed pattern and its cue: STOP, ARRIVED, REROUTE, NO_PATH, WAIT, OFF.

        ``reason`` is for the caller's status and logs; the voice says the phrase only.
        TURN_AROUND needs a direction: ``guide`` produces it.
        """
        del reason
        if kind in (PatternKind.GUIDE, PatternKind.TURN_AROUND):
            raise ValueError(f"{kind} comes from guide(), which knows the direction")
        if kind is not PatternKind.ARRIVED:
            self._announced = None  # after any event, the next direction is worth saying
        if self.sole is not None and kind in SAFETY_KINDS:
            self.sole.after_safety()
        return GuidanceOutput(self.patterns.event(kind, now), self.cues.event(kind, now))

    def guide(
        self,
        path: np.ndarray,
        pose: Pose,
        shape: tuple[int, int],
        now: float,
        blocked: np.ndarray | None = None,
        occupancy: np.ndarray | None = None,
        map_version: int | None = None,
    ) -> GuidanceOutput:
        """Guide along ``path`` ((k, 2) cells from the user's cell to the goal). ``occupancy``
        (the known map, not inflated) lets a sole voice stop the user before contact.
        ``map_version``: moved on whenever ``blocked`` changes in place (``InflatedMap.version``);
        given, the turning points of an unchanged path ahead on an unchanged map are reused."""
        path = np.asarray(path)
        if path.ndim != 2 or len(path) == 0:
            return self.event(PatternKind.NO_PATH, now)
        user = xy_to_continuous(shape, pose.x, pose.y, self.cell_m)
        goal = path[-1].astype(np.float64) + 0.5
        if float(np.hypot(*(goal - user))) * self.cell_m <= self.arrive_m:
            return self.event(PatternKind.ARRIVED, now)

        pts = self._points(path, blocked, map_version)
        target = self._target(pts, user, blocked)
        rel = relative_angle(bearing(shape, user, target), pose.heading)
        change = self.route_watch.check(path, self.cell_m)

        verdict = self.hold.update(path, user, blocked, self.cell_m, now)
        if verdict == "hold":
            return self.event(PatternKind.WAIT, now)
        if verdict == "expired":
            return self.event(PatternKind.REROUTE, now)

        if change is None:
            self.route_watch.keep(path, self.cell_m)  # from here on the user is guided on it
        metres = float(np.hypot(*(target - user))) * self.cell_m
        target_xy = (float(target[1] * self.cell_m), float((shape[0] - target[0]) * self.cell_m))
        cw = -rel
        if abs(rel) > self.turn_around:
            self.hysteresis.reset()
            pattern = self.patterns.turn_around(cw, now)
            if change is not None:  # the new way lies behind: said as the new route
                cue = self.cues.route_change(change, rel, metres, now)
                if cue is not None:
                    self.route_watch.keep(path, self.cell_m)
            else:
                cue = self.cues.event(PatternKind.TURN_AROUND, now)
            self._announced = None
            if self.sole is not None:
                self.sole.after_safety()
            return GuidanceOutput(pattern, cue, target_xy)
        if self.sole is not None:
            danger, stop = self.sole.stop_before_contact(
                occupancy, blocked, user, pose.heading, self.cell_m, now
            )
            if danger:  # said now, or less than a second ago: either way no step that way
                return GuidanceOutput(self.patterns.event(PatternKind.STOP, now), stop, target_xy)
        if change is not None:
            cue = self.cues.route_change(change, rel, metres, now)
            if cue is not None:  # the distinct pattern once, with the new direction in words
                self.route_watch.keep(path, self.cell_m)
                self._announced = (target.copy(), clock_hour(rel))
                if self.sole is not None:
                    self.sole.said_way(target, now)
                return GuidanceOutput(self.patterns.event(PatternKind.REROUTE, now), cue, target_xy)
        felt = self.hysteresis(cw)
        clearance = forward_clearance_m(blocked, user, pose.heading, self.cell_m)
        pattern = self.patterns.guide(felt, clearance, now)
        if self.sole is not None:
            cue = self.sole.way(
                target, user, rel, metres, self.cell_m, now, occupancy, pose.heading
            )
        else:
            cue = self._direction_cue(target, rel, metres, now)
        if cue is None and bool(np.all(np.abs(target - goal) < 1e-9)):
            cue = self._count_down(metres, now)
        return GuidanceOutput(pattern, cue, target_xy)

    def _count_down(self, metres: float, now: float) -> VoiceCue | None:
        """On the last leg, the distance left as it passes each of ``COUNTDOWN_M``, once."""
        due = [m for m in COUNTDOWN_M if metres <= m and m not in self._countdown]
        if not due:
            return None
        cue = self.cues.goal_in(metres, now)
        if cue is not None:
            self._countdown.update(due)
        return cue

    def _points(
        self, path: np.ndarray, blocked: np.ndarray | None, version: int | None = None
    ) -> np.ndarray:
        # Only the next leg or two matter to the user (the target and its distance): a leg is
        # at most max_leg long, so the path beyond a few legs' worth of cells is not looked at.
        path = path[: int(2.5 * self.max_leg_cells) + 2]
        if self.smooth and blocked is not None and len(path) > 2:
            own = planner_band(self.planner()) if self.planner is not None else None
            smoothed = own(path, blocked) if own else rubber_band(path, blocked, cell_m=self.cell_m)
            return turning_points_from_polyline(smoothed, blocked, self.max_leg_cells)
        return self._kept_points(path, blocked, self.max_leg_cells, version)

    def _target(self, pts: np.ndarray, user: np.ndarray, blocked: np.ndarray | None) -> np.ndarray:
        """The next turning point: skip those already reached, or visible past the next one.

        A user standing inside the inflated margin (a newly seen obstacle, or drift) sees no
        line free from its own cell. There the first ``escape_m`` of a line are not checked:
        shorter than the user's radius, that stretch cannot cross an obstacle cell and be out
        of the margin again, so a line free after it is safe; otherwise the user is led to
        the way out (the path's next point) first.
        """
        i = 1 if len(pts) > 1 else 0
        if blocked is None:
            while i + 1 < len(pts) and self._dist_m(pts[i], user) <= self.reach_m:
                i += 1
            return pts[i]
        r, c = int(user[0]), int(user[1])
        # A line may shave the outer half of the margin (segment_clear): in a doorway-narrow
        # free channel no straight line stays wholly free, and a user told to zig-zag between
        # path cells walks further and turns more than one told to walk on. A user already
        # deeper than that is "in the margin": only the escape stretch is not checked.
        inside = 0 <= r < blocked.shape[0] and 0 <= c < blocked.shape[1]
        in_margin = inside and bool(blocked[r, c]) and is_core(blocked, r, c, self.shave_cells)
        skip = self.escape_m / self.cell_m if in_margin else 0.0
        depth = 0 if in_margin else self.shave_cells
        while i + 1 < len(pts):
            near = not in_margin and self._dist_m(pts[i], user) <= self.reach_m
            if not (near or _free_after(blocked, user, pts[i + 1], skip, depth)):
                break
            i += 1
        return pts[i]

    def _dist_m(self, a: np.ndarray, b: np.ndarray) -> float:
        return float(np.hypot(*(a - b))) * self.cell_m

    def _direction_cue(
        self, target: np.ndarray, rel: float, metres: float, now: float
    ) -> VoiceCue | None:
        """Speak on a new leg or when the clock hour moved by two or more, and to reassure on
        a long leg every ``reassure_s``; else stay quiet."""
        hour = clock_hour(rel)
        if self._announced is not None:
            old_target, old_hour = self._announced
            moved = float(np.hypot(*(target - old_target))) * self.cell_m
            turned = min((hour - old_hour) % 12, (old_hour - hour) % 12)
            reassure = (
                self.reassure_s > 0
                and metres >= REASSURE_MIN_M
                and now - self._announced_at >= self.reassure_s
            )
            if moved < 1.0 and turned < 2 and not reassure:
                return None
        cue = self.cues.direction(rel, metres, now)
        if cue is not None:
            self._announced = (target.copy(), hour)
            self._announced_at = now
        return cue


def _free_after(
    blocked: np.ndarray, a: np.ndarray, b: np.ndarray, skip_cells: float, depth: int
) -> bool:
    """``segment_clear`` from ``skip_cells`` along a→b to b (the whole segment when 0)."""
    length = float(np.hypot(*(b - a)))
    if skip_cells > 0.0:
        if length <= skip_cells:
            return True  # b itself is a path point: free
        a = a + (b - a) * (skip_cells / length)
    return bool(segment_clear(blocked, a[0], a[1], b[0], b[1], depth))


@numba.njit(cache=True, nogil=True)
def _shortcuts(poly: np.ndarray, blocked: np.ndarray, max_leg_cells: float) -> np.ndarray:
    n = poly.shape[0]
    out = np.empty((n, 2), dtype=np.float64)
    out[0] = poly[0]
    m, i = 1, 0
    while i < n - 1:
        j = i + 1
        while j + 1 < n:
            r0, c0, r1, c1 = poly[i, 0], poly[i, 1], poly[j + 1, 0], poly[j + 1, 1]
            if math.hypot(r1 - r0, c1 - c0) > max_leg_cells or not segment_free(
                blocked, r0, c0, r1, c1
            ):
                break
            j += 1
        out[m] = poly[j]
        m += 1
        i = j
    return out[:m].copy()


def turning_points_from_polyline(
    poly: np.ndarray, blocked: np.ndarray, max_leg_cells: float
) -> np.ndarray:
    """Turning points of an already smooth polyline (continuous cell units): greedy shortcuts
    (compiled: a band of one point per cell took ~1 ms a guidance call in Python)."""
    poly = np.ascontiguousarray(poly, dtype=np.float64)
    return _shortcuts(poly, np.ascontiguousarray(blocked, dtype=np.bool_), float(max_leg_cells))
