"""Seed 004's camera map to the daemon: colour frames in, ``MapDelta`` and the goal out.

Rettkowski et al. (seed 004, §V) turn each Kinect colour image into a bird's-eye view,
threshold it in HSV into a binary map (obstacles purple, the target green) and hand the map
and the target's place to the robot's path planner. Here that planner is the daemon:
``BirdsEyeMapper`` lays each frame's bird's-eye map onto the user's global grid with the
camera's pose (obstacle pixels OCCUPIED, the rest of the floor patch FREE), and
``BirdsEyeNode`` publishes what changed as numbered ``MapDelta``s (the mapper's contract of
``mapper/node.py``: delta 0 the start map, a ``MAP_SOURCE`` snapshot after a gap), the target
as the user's ``Goal`` once seen (again only when it moved by ``goal_move_m``), and with
every frame a ``Proximity`` that says whether the frame saw the target: the daemon tells a
user with no goal to turn and look (``PatternKind.LOOK``) until it does.

A frame without a colour image or a pose, of another size than the view was built for, or
not newer than the last, is refused whole and counted; the map is untouched.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass

import numpy as np
import zenoh

from protocol import codec
from protocol import session as wire
from protocol import topics as T
from protocol.messages import Goal, GoalMetres, Proximity

from ..camera_model import rotation_of
from ..frame import DepthFrame, FrameRejected, Refusal
from ..node import MapperNode
from ..occupancy_mapper import FREE, OCCUPIED, UNKNOWN
from .view import BirdsEye


@dataclass(frozen=True)
class BirdsEyeSettings:
    shape: tuple[int, int] = (100, 100)
    cell_m: float = 0.10
    goal_move_m: float = 0.3
    """The goal is sent again only when the target's place moved this far (a replan each)."""


@dataclass
class BirdsEyeResult:
    cells: np.ndarray
    values: np.ndarray
    target_xy: tuple[float, float] | None
    """The target's centre in the world (metres), or None when the frame did not see it."""


class BirdsEyeMapper:
    """One user's grid from seed 004's bird's-eye maps."""

    def __init__(self, view: BirdsEye, width: int, height: int,
                 settings: BirdsEyeSettings | None = None) -> None:  # fmt: skip
        self.view = view
        self.size = (width, height)
        """The colour image size the view's homography was built for."""
        self.settings = settings or BirdsEyeSettings()
        self.occupancy = np.full(self.settings.shape, UNKNOWN, np.uint8)
        self.last_stamp: float | None = None
        self.backend = "opencv"

    @classmethod
    def for_frame(cls, frame: DepthFrame,
                  settings: BirdsEyeSettings | None = None) -> BirdsEyeMapper:  # fmt: skip
        """The view of the camera that took ``frame``: its intrinsics, height and pitch (seed
        004 fixes the trapezoid once, for the camera's mounting)."""
        if frame.intrinsics is None or frame.pose is None:
            raise FrameRejected(Refusal.NO_INTRINSICS, "the first frame must say its camera")
        k = frame.intrinsics
        body = rotation_of(frame.pose.orientation)
        pitch = math.asin(max(-1.0, min(1.0, -float(body[2, 0]))))  # nose down positive
        view = BirdsEye(k, frame.pose.position[2], pitch)
        return cls(view, k.width, k.height, settings)

    def _check(self, frame: DepthFrame) -> tuple[np.ndarray, float, float, float]:
        if frame.pose is None:
            raise FrameRejected(Refusal.NO_POSE, "the frame has no camera pose")
        colour = frame.color
        w, h = self.size
        if not isinstance(colour, np.ndarray):
            raise FrameRejected(Refusal.NO_COLOUR, "the frame has no colour image")
        if colour.shape != (h, w, 3) or colour.dtype != np.uint8:
            why = f"colour {colour.shape} {colour.dtype}, the view wants ({h}, {w}, 3) uint8"
            raise FrameRejected(Refusal.WRONG_SIZE, why)
        if not math.isfinite(frame.stamp) or frame.stamp < 0:
            raise FrameRejected(Refusal.STALE, f"stamp {frame.stamp!r} is not a time")
        if self.last_stamp is not None and frame.stamp <= self.last_stamp:
            why = f"stamp {frame.stamp:.3f} is not after the last frame's {self.last_stamp:.3f}"
            raise FrameRejected(Refusal.STALE, why)
        x, y, _ = frame.pose.position
        return colour, x, y, frame.pose.heading

    def process(self, frame: DepthFrame) -> BirdsEyeResult:
        colour, x, y, heading = self._check(frame)
        s = self.settings
        obstacles, target = self.view(colour)
        occupied = self.view.cells(obstacles, x, y, heading, s.shape, s.cell_m)
        floor = self.view.cells(1 - obstacles, x, y, heading, s.shape, s.cell_m)
        free = np.setdiff1d(floor, occupied, assume_unique=True)
        cells = np.concatenate((occupied, free))
        values = np.concatenate((np.full(occupied.size, OCCUPIED, np.uint8),
                                 np.full(free.size, FREE, np.uint8)))  # fmt: skip
        changed = self.occupancy.reshape(-1)[cells] != values
        cells, values = cells[changed], values[changed]
        seen = self.view.target_xy(target)
        where = None
        if seen is not None:
            fwd, left = seen
            c, si = math.cos(heading), math.sin(heading)
            where = (x + fwd * c - left * si, y + fwd * si + left * c)
        # Everything is known: only now does the map change.
        self.occupancy.reshape(-1)[cells] = values
        self.last_stamp = frame.stamp
        return BirdsEyeResult(cells, values, where)


class BirdsEyeNode(MapperNode):
    """``MapperNode``'s delta contract, fed by colour frames; the goal and ``target_seen``
    besides."""

    mapper: BirdsEyeMapper  # type: ignore[assignment]

    def __init__(self, session: zenoh.Session, user: str, mapper: BirdsEyeMapper) -> None:
        super().__init__(session, user, mapper)  # type: ignore[arg-type]
        self._goal = wire.declare_publisher(session, T.GOAL, user)
        self.goal_xy: tuple[float, float] | None = None
        self.goals_sent = 0

    def feed(self, frame: DepthFrame) -> BirdsEyeResult | None:  # type: ignore[override]
        result = self._map_and_publish(frame)
        if result is None:
            return None
        t = result.target_xy
        s = self.mapper.settings
        if t is not None and (self.goal_xy is None
                              or math.dist(t, self.goal_xy) >= s.goal_move_m):  # fmt: skip
            goal = Goal(target=GoalMetres(x=t[0], y=t[1]), stamp=time.time())
            self._goal.put(codec.encode(goal))
            self.goal_xy, self.goals_sent = t, self.goals_sent + 1
        seen = Proximity(target_seen=t is not None, frame_stamp=frame.stamp, stamp=time.time())
        self._prox.put(codec.encode(seen))
        return result

    def close(self) -> None:
        self._goal.undeclare()
        super().close()
