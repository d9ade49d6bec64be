"""After a STOP before contact: no GUIDE back into the side that is blocked.

The STOP (``proximity``) is taken from the camera's frame, relative to the body, so it holds
whatever the pose is worth. The GUIDE that follows it is not: it comes from the planner's map
and the estimated pose, and when the estimate is off by more than the margin (an RFID pose
0.3-1 m wrong) it points straight back at the obstacle the user was just stopped in front of.
So from a STOP on, the obstacle points the camera reported are kept, and every GUIDE is
checked against them in the body frame before it goes to the belt:

- the points are kept in the frame of the poses (the estimate plus the reading), so when the
  user turns or steps they move with the dead-reckoned pose: an obstacle the camera no longer
  sees once the user turned away is still felt (otherwise the next GUIDE turns the user back
  to face it: a STOP, a turn away, a turn back, for ever). An offset of the whole estimate
  moves the points with it, so what is relative stays right;
- the frame's nearest obstacle bounds it: when the obstacle is convex its nearest point lies
  on a line square to its bearing with the whole obstacle beyond (the nearest point of a
  convex set bounds it by that half-plane), so a straight step at bearing δ has a free run of
  (r − margin) / cos(δ − φ) towards it, and none is in the way when cos(δ − φ) ≤ 0. A kept
  point is no nearest point once the user has moved (a wall's points beside a corridor would
  close it), so each is a disc of ``point_m`` that a step must not cross;
- a direction keeps its GUIDE when its free run, over the belt's reading error either side,
  is at least ``min_run_m``; its pulse then follows that free run as it follows the map's
  clearance (``pulse_period_ms``), so the user's steps shorten with the distance left;
- otherwise the GUIDE turns to the nearest direction with ``turn_run_m`` free, away from the
  blocked side; with none at all the user is told to stop.

The memory is armed by a STOP and lasts ``memory_s`` after the last reading within
``stop_m``; before the first STOP guidance is untouched.
"""

from __future__ import annotations

import math
from collections import deque
from dataclasses import dataclass

from daemon.guidance.guide import Guidance
from daemon.guidance.patterns import angle_diff, decode, pulse_period_ms
from protocol.messages import PatternKind, Pose, Proximity

from .inbox import StepOutput


@dataclass(frozen=True)
class BlockedSideSettings:
    memory_s: float = 6.0
    """How long the points are kept after the last reading within the STOP distance."""
    keep_m: float = 0.6
    """Readings nearer than this (the STOP's distance) are kept: further ones are beyond a
    step. With 1.2 m, the points of a cluttered passage, kept 6 s, closed it (12 hard walks:
    9 arrived against 12, counting the spread and the runs below as well)."""
    margin_m: float = 0.05
    """Taken off the nearest obstacle's free run: a reading is to the nearest edge of a cell."""
    point_m: float = 0.12
    """A kept point's radius: a 0.1 m cell's half-diagonal (0.07 m) and the margin."""
    spread_deg: float = 10.0
    """A direction is checked with this much either side: the user's reading of the belt
    (8° error) and their gait (4°), about one standard deviation of both."""
    min_run_m: float = 0.18
    """A GUIDE keeps its direction with at least this free: at the belt's fastest pulse a
    step is a quarter of one (at most about 0.16 m)."""
    turn_run_m: float = 0.3
    """A GUIDE turned away points where at least this is free (0.6 m: in 40-60 % clutter
    there was often none, and the user stood)."""
    max_points: int = 64


class BlockedSide:
    def __init__(self, stop_m: float, settings: BlockedSideSettings | None = None) -> None:
        self.stop_m = stop_m
        self.settings = settings or BlockedSideSettings()
        self.points: deque[tuple[float, float]] = deque(maxlen=self.settings.max_points)
        self.nearest: tuple[float, float] | None = None
        """This frame's nearest obstacle point (the half-plane bound); None when none."""
        self.until = -math.inf
        self.turned = 0
        """GUIDEs turned away from a blocked side so far."""

    def arm(self, now: float) -> None:
        """A STOP before contact: from now on, GUIDE is checked against what was seen."""
        self.until = now + self.settings.memory_s

    def steer(self, proximity: Proximity | None, pose: Pose | None, now: float,
              guidance: Guidance, out: StepOutput) -> None:  # fmt: skip
        """Keep this frame's readings and check this step's GUIDE against all kept.

        Only for an estimated pose (one with a sigma, as the RFID filter sends): an exact
        pose's map holds what was seen and the step's direction already keeps clear of it
        (``clear_way``); turning it again from body-frame points bumped known corners (camera
        walks, 13 bumps)."""
        if pose is not None and pose.sigma_m is None:
            return
        if now > self.until or pose is None:
            self.points.clear()
            self.nearest = None
            return
        s = self.settings
        if proximity is not None:
            self.nearest = None
            readings = [(proximity.ahead_m, 0.0), (proximity.nearest_m, proximity.bearing)]
            for dist, bearing in readings:
                if dist is None or bearing is None or dist >= s.keep_m:
                    continue
                if dist < self.stop_m:
                    self.until = now + s.memory_s
                a = pose.heading + bearing
                point = (pose.x + dist * math.cos(a), pose.y + dist * math.sin(a))
                self.points.append(point)
                self.nearest = point  # the second reading, the nearest, wins
        if not out.belt or out.belt[-1].kind != PatternKind.GUIDE or not self.points:
            return
        last = out.belt[-1]
        cw = decode(last.motors)
        if cw is None:
            return
        rel = -cw  # CCW from the front, as the bearings
        run = self.free_run(rel, pose)
        if run >= s.min_run_m:
            period = _faster(last.period_ms, pulse_period_ms(run))
            if period != last.period_ms:  # not published yet: the same pattern, faster
                out.belt[-1] = last.model_copy(update={"period_ms": period})
            return
        away = self.turn_away(rel, pose)
        self.turned += 1
        if away is None:
            out.belt[-1] = guidance.patterns.event(PatternKind.STOP, now)
            return
        out.belt[-1] = guidance.patterns.guide(-away, self.free_run(away, pose), now)

    def free_run(self, rel: float, pose: Pose) -> float:
        """Metres a straight step at ``rel`` (radians CCW from the front, give or take the
        spread) may go before the nearest kept obstacle's bounding line."""
        spread = math.radians(self.settings.spread_deg)
        return min(self._run(rel + d, pose) for d in (-spread, 0.0, spread))

    def turn_away(self, rel: float, pose: Pose) -> float | None:
        """The direction nearest ``rel`` with ``turn_run_m`` free, 10° apart; on a tie the
        side with more room."""
        best: tuple[float, float] | None = None
        for k in range(1, 19):
            for sign in (1.0, -1.0):
                d = angle_diff(rel + sign * math.radians(10 * k), 0.0)
                run = self.free_run(d, pose)
                if run >= self.settings.turn_run_m and (best is None or run > best[1]):
                    best = (d, run)
            if best is not None:
                return best[0]
        return None

    def _run(self, rel: float, pose: Pose) -> float:
        a = pose.heading + rel
        ux, uy = math.cos(a), math.sin(a)
        rho = self.settings.point_m
        run = math.inf
        for px, py in self.points:
            dx, dy = px - pose.x, py - pose.y
            along = dx * ux + dy * uy
            across = abs(dx * uy - dy * ux)
            if math.hypot(dx, dy) <= rho:
                if along > 0:
                    run = 0.0
            elif along > 0 and across < rho:
                run = min(run, along - math.sqrt(rho * rho - across * across))
        if self.nearest is not None:
            dx, dy = self.nearest[0] - pose.x, self.nearest[1] - pose.y
            r = math.hypot(dx, dy)
            towards = (dx * ux + dy * uy) / r if r > 1e-9 else 1.0
            if towards > 1e-6:
                run = min(run, max(0.0, r - self.settings.margin_m) / towards)
        return max(0.0, run)


def _faster(a: int, b: int) -> int:
    """The faster of two pulse periods (0: steady, the slowest)."""
    if a == 0 or b == 0:
        return a or b
    return min(a, b)
