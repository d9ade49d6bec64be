"""Where am I: distance and clock direction to the goal and to the next turn, in words.

Answers the belt's where-am-I button (``PATTERNS.md``): "goal 23 metres at 2 o'clock; next
turn 4 metres at 12 o'clock". Clock hours as in every other cue (``cues.clock_hour``: 12 is
straight ahead, 3 the right hand); distances rounded as ``cues.say_distance`` says them.
The goal's distance is along the route when the route is known (what the user will walk),
its direction the straight line (where it is); the next turn is the turning point the
belt is pointing to.
"""

from __future__ import annotations

import math

from protocol.messages import Pose

from .cues import PHRASES, Lang, clock_hour, say_distance
from .turning_points import relative_angle

SAME_PLACE_M = 0.5
"""A next turn this close to the goal is the goal: not said twice."""


def _toward(pose: Pose, x: float, y: float) -> tuple[float, float]:
    """Straight-line distance (m) and direction relative to the user (rad, + = left)."""
    dx, dy = x - pose.x, y - pose.y
    return math.hypot(dx, dy), relative_angle(math.atan2(dy, dx), pose.heading)


def where_text(
    lang: Lang,
    pose: Pose | None,
    goal_xy: tuple[float, float] | None,
    route_m: float | None = None,
    turn_xy: tuple[float, float] | None = None,
) -> str:
    """The spoken answer; ``route_m`` is the route's length to the goal, if known."""
    p = PHRASES[lang]
    if goal_xy is None:
        return p["where_no_goal"]
    if pose is None:
        return p["where_no_pose"]
    straight, rel = _toward(pose, *goal_xy)
    metres = route_m if route_m is not None else straight
    parts = [p["where_goal"].format(dist=say_distance(metres, lang), hour=clock_hour(rel))]
    if turn_xy is not None and math.dist(turn_xy, goal_xy) > SAME_PLACE_M:
        turn_m, turn_rel = _toward(pose, *turn_xy)
        parts.append(
            p["where_turn"].format(dist=say_distance(turn_m, lang), hour=clock_hour(turn_rel))
        )
    return "; ".join(parts)
