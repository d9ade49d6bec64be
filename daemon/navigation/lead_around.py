"""After a STOP's hold: the GUIDE leads around what the latest frame shows ahead, not into it.

A STOP before contact is held for ``hold_s``; then "guidance leads around it" — but the GUIDE
comes from the planner's map, and a person who has just stood still is not on the map yet:
the path runs straight through them. In a camera walk (seed 11) the hold ended, GUIDE said
straight on at the fastest pulse, the frame showed the person 1 mm-8 cm ahead, and the
user's short steps crept in under ``rearm_m`` to contact. A STOP in place of that GUIDE
stood the RFID belt walks at their action limit (the user never left), so the GUIDE is
turned instead, the way ``blocked_side`` turns it for estimated poses:

- the frame bounds what the user may walk into, in the body frame: the corridor's obstacle
  ``ahead_m`` straight on and the nearest one at ``bearing``, each as a line square to its
  bearing with the obstacle beyond (the nearest point of a convex obstacle bounds it so), so
  a straight step at δ has a free run of (r − margin) / cos(δ − φ) towards it;
- the GUIDE keeps its direction when that run, over the belt's reading error either side,
  reaches the STOP's own distance: the user is led out of the STOP's reach or along its
  edge, never deeper in;
- otherwise it turns to the nearest such direction (10° apart, either side of the GUIDE's)
  whose step also keeps clear of the map's known obstacles (``clear_way``'s cone from where
  the user stands); with none, the roomiest such map-clear direction if a short step is free
  there, else the user is told to stop (a STOP there stood seed 11's user for minutes);
- only an obstacle the map does not hold starts this: what it holds, the planner's path and
  ``keep_clear`` keep off (leading around every wall and box turned a walk in place for
  300 s). The one it starts for is kept in the world for a while (``LeadAround``), and a
  turned GUIDE keeps off everything the frame shows within ``stop_m``, mapped or not, and
  pulses for the room left (turned by the kept person alone, one went at a steady pulse into
  a mapped person 0.35 m away).

This is for an exact pose (the camera's own, as in the camera walks). An estimated pose's
GUIDE is turned by ``blocked_side``, which keeps the STOP's points and lets a GUIDE with a
short step free keep its direction (the RFID belt walks arrive with it).
"""

from __future__ import annotations

import math

import numpy as np

from daemon.guidance.patterns import PatternMaker, angle_diff, decode
from daemon.planning.grid import OCCUPIED
from protocol.messages import BeltPattern, PatternKind, Pose, Proximity

from .blocked_side import BlockedSide, BlockedSideSettings
from .clear_way import STEP_MAX_M, cone_clear

SIDE = BlockedSideSettings()
"""The reading error either side of a direction and the margin off a reading, as for an
estimated pose's blocked side."""


def free_run(rel: float, proximity: Proximity) -> float:
    """Metres a straight step at ``rel`` (radians CCW from the front, give or take the
    reading error) may go before a bounding line of the frame's obstacles."""
    spread = math.radians(SIDE.spread_deg)
    readings = [(proximity.ahead_m, 0.0), (proximity.nearest_m, proximity.bearing)]
    run = math.inf
    for dist, bearing in readings:
        if dist is None or bearing is None:
            continue
        for d in (-spread, 0.0, spread):
            towards = math.cos(rel + d - bearing)
            if towards > 1e-6:
                run = min(run, max(0.0, dist - SIDE.margin_m) / towards)
    return run


def on_map(seen: Proximity, pose: Pose, occupancy: np.ndarray, cell_m: float) -> bool:
    """Whether the map holds the frame's obstacle ahead: an OCCUPIED cell within one cell of
    the reading's point (a reading is to a cell's nearest edge, its centre half a cell on)."""
    if seen.ahead_m is None:
        return False
    d = seen.ahead_m + cell_m / 2
    x, y = pose.x + d * math.cos(pose.heading), pose.y + d * math.sin(pose.heading)
    r, c = occupancy.shape[0] - 1 - math.floor(y / cell_m), math.floor(x / cell_m)
    window = occupancy[max(0, r - 1) : max(0, r + 2), max(0, c - 1) : max(0, c + 2)]
    return bool((window == OCCUPIED).any())


def on_free_map(occupancy: np.ndarray, pose: Pose, cell_m: float) -> bool:
    """Whether the pose lies on the map in a cell not OCCUPIED."""
    h, w = occupancy.shape
    r, c = h - 1 - math.floor(pose.y / cell_m), math.floor(pose.x / cell_m)
    return 0 <= r < h and 0 <= c < w and occupancy[r, c] != OCCUPIED


class LeadAround:
    """The hold's obstacle kept where it stands in the world, for an exact pose: once the
    user has turned away the frame no longer shows it, and the planner's next GUIDE (the map
    still without it) turns them back to face it: a STOP, a turn away, a turn back, for
    ever, never a step (a camera walk, seed 11: 55 turns and 29 steps in 300 s, timed out).
    So the readings of the steps after the hold are kept as discs (``blocked_side``'s
    ``point_m``) for ``memory_s`` after the last, and every GUIDE is checked against them
    too; the user goes on past the person."""

    def __init__(self, stop_m: float) -> None:
        self.stop_m = stop_m
        self.kept = BlockedSide(stop_m)
        """Its points and their free run (no nearest-point bound: the user has moved)."""
        self.led = 0
        """GUIDEs turned away (or made STOP) so far."""

    def steer(self, pattern: BeltPattern, seen: Proximity | None, pose: Pose,
              occupancy: np.ndarray, cell_m: float, patterns: PatternMaker, now: float,
              held: bool = True) -> BeltPattern | None:  # fmt: skip
        """This step's GUIDE turned away from the hold's obstacle, or None. ``seen``: the
        latest frame when it shows an obstacle within ``stop_m``; ``held``: this step comes
        after a hold for it (only then is it kept)."""
        points = self.kept.points
        # What the map holds, the planner's path and ``keep_clear`` keep off: not kept, and
        # no reason to turn; but a GUIDE that is turned keeps off it too.
        if held and seen is not None and not on_map(seen, pose, occupancy, cell_m):
            for dist, bearing in ((seen.ahead_m, 0.0), (seen.nearest_m, seen.bearing)):
                if dist is not None and bearing is not None and dist < self.stop_m:
                    a = pose.heading + bearing
                    points.append((pose.x + dist * math.cos(a), pose.y + dist * math.sin(a)))
            self.kept.until = now + SIDE.memory_s
        if now > self.kept.until:
            points.clear()
        if not points:
            return None
        led = lead_around(pattern, seen, pose, occupancy, cell_m, self.kept, patterns, now)
        self.led += led is not None
        return led


def lead_around(
    pattern: BeltPattern,
    seen: Proximity | None,
    pose: Pose,
    occupancy: np.ndarray,
    cell_m: float,
    kept: BlockedSide,
    patterns: PatternMaker,
    now: float,
) -> BeltPattern | None:
    """The GUIDE turned away from the hold's obstacle (or a STOP if the frame still shows it
    and no way is clear), or None when ``pattern`` keeps clear of it: ``kept.stop_m`` from
    what the frame shows, ``turn_run_m`` from the kept discs."""
    if pattern.kind != PatternKind.GUIDE:
        return None
    cw = decode(pattern.motors)
    if cw is None:
        return None
    rel = -cw  # CCW from the front, as the bearings

    def run(r: float) -> float:
        disc = kept.free_run(r, pose) if kept.points else math.inf
        return min(disc / SIDE.turn_run_m, free_run(r, seen) / kept.stop_m if seen else math.inf)

    if run(rel) >= 1.0:
        return None
    k = np.arange(1, 19)
    offsets = np.ravel(np.column_stack([k, -k])) * math.radians(10.0)
    rels = [angle_diff(rel + o, 0.0) for o in offsets]
    runs = np.array([run(r) for r in rels])
    headings = pose.heading + np.array(rels)
    mapped = cone_clear(occupancy, pose.x, pose.y, headings, STEP_MAX_M, cell_m)
    if not mapped.any() and not on_free_map(occupancy, pose, cell_m):
        mapped[:] = True  # a pose on an obstacle or off the map: the frame alone decides
    ok = np.flatnonzero((runs >= 1.0) & mapped)
    if ok.size == 0:
        # No way with that much room: the roomiest clear of the map, if a short step is free
        # (in a narrow passage a STOP here stood the user for minutes: seed 11, 268 STOPs).
        best = int(np.argmax(np.where(mapped, runs, -1.0)))
        if mapped[best] and runs[best] * SIDE.turn_run_m >= SIDE.min_run_m:
            ok = np.array([best])
        elif seen is not None:
            return patterns.event(PatternKind.STOP, now)  # the frame shows it within stop_m
        else:
            return None  # the frame is clear ahead and its STOP guards the step
    away = rels[int(ok[0])]
    room = min(kept.free_run(away, pose), free_run(away, seen) if seen else math.inf)
    return patterns.guide(-away, min(room, 1.0), now)  # its pulse: steps as short as the room
