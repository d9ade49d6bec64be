"""What the view knows of each user: the latest of every message, folded as it arrives.

Everything here is bounded, whatever the walk's length: one map per user (replaced in place
by deltas), the latest path, pose, goal, belt pattern and status, and a short ring of voice
cues. Zenoh's threads write (``fold``), the web app's loop reads (``frame``), under one lock
held only for a few field assignments.
"""

from __future__ import annotations

import threading
import time
from collections import deque
from dataclasses import dataclass, field

import numpy as np

from protocol.messages import (
    BeltPattern,
    Goal,
    GoalCell,
    GoalMetres,
    MapDelta,
    MapSnapshot,
    Message,
    NavPath,
    NavStatus,
    Pose,
    VoiceCue,
)

MAX_USERS = 16
"""More users than a daemon serves by default (8): a key flood cannot grow the view."""
CUES_KEPT = 6
DEFAULT_CELL_M = 0.10


@dataclass
class UserView:
    map: np.ndarray | None = None
    map_seq: int = -1
    map_version: int = 0
    """Bumped on every change of the map, so the page fetches the image only then."""
    needs_snapshot: bool = True
    """No map yet, or a delta sequence gap: ask the daemon for its snapshot."""
    path: NavPath | None = None
    pose: Pose | None = None
    goal: Goal | None = None
    belt: BeltPattern | None = None
    status: NavStatus | None = None
    cues: deque[VoiceCue] = field(default_factory=lambda: deque(maxlen=CUES_KEPT))
    latency_ms: float | None = None
    """Pose stamped → the path planned from it received here: the user's loop as seen live."""
    messages: int = 0
    updated: float = 0.0


class ViewState:
    """Every user's ``UserView``; at most ``max_users`` of them (later ones are ignored)."""

    def __init__(self, max_users: int = MAX_USERS, cell_m: float = DEFAULT_CELL_M) -> None:
        self.max_users = max_users
        self.cell_m = cell_m
        self.users: dict[str, UserView] = {}
        self.daemon_alive = False
        self.ignored = 0
        """Messages for users past ``max_users``."""
        self._lock = threading.Lock()

    def _user(self, user: str) -> UserView | None:
        view = self.users.get(user)
        if view is None and len(self.users) < self.max_users:
            view = self.users[user] = UserView()
        if view is None:
            self.ignored += 1
        return view

    def set_alive(self, alive: bool) -> None:
        with self._lock:
            self.daemon_alive = alive
            if alive:  # a restarted daemon starts from an empty map: ask it again
                for view in self.users.values():
                    view.needs_snapshot = True

    def fold(self, user: str, msg: Message, received: float | None = None) -> None:
        """Take one decoded message of ``user`` into the view."""
        now = time.time() if received is None else received
        with self._lock:
            view = self._user(user)
            if view is None:
                return
            view.messages += 1
            view.updated = now
            if isinstance(msg, MapDelta):
                self._apply_delta(view, msg)
            elif isinstance(msg, MapSnapshot):
                self._apply_snapshot(view, msg)
            elif isinstance(msg, NavPath):
                view.path = msg
                self.cell_m = msg.cell_m
                view.latency_ms = max(0.0, (now - msg.pose_stamp) * 1e3)
            elif isinstance(msg, Pose):
                view.pose = msg
            elif isinstance(msg, Goal):
                view.goal = msg
            elif isinstance(msg, BeltPattern):
                view.belt = msg
            elif isinstance(msg, NavStatus):
                view.status = msg
            elif isinstance(msg, VoiceCue):
                view.cues.append(msg)

    def _apply_delta(self, view: UserView, delta: MapDelta) -> None:
        shape = (delta.height, delta.width)
        if view.map is None or view.map.shape != shape or delta.seq == 0:
            if delta.seq != 0:
                view.needs_snapshot = True
                return
            view.map = np.full(shape, 0, dtype=np.uint8)  # unknown is drawn as free, as planned
        elif delta.seq != view.map_seq + 1:
            view.needs_snapshot = True
            if delta.seq <= view.map_seq:
                return  # already in the map (a snapshot overtook it)
        view.map.reshape(-1)[delta.cell_array()] = delta.value_array()
        view.map_seq = delta.seq
        view.map_version += 1
        if delta.seq == 0:
            view.needs_snapshot = False

    def _apply_snapshot(self, view: UserView, snap: MapSnapshot) -> None:
        if snap.seq < view.map_seq and view.map is not None and not view.needs_snapshot:
            return
        view.map = snap.array()
        view.map_seq = snap.seq
        view.map_version += 1
        view.needs_snapshot = False

    def wanting_snapshot(self) -> list[str]:
        with self._lock:
            return [u for u, v in self.users.items() if v.needs_snapshot]

    def map_of(self, user: str) -> tuple[np.ndarray, int] | None:
        """A copy of ``user``'s map and its version (None before any map)."""
        with self._lock:
            view = self.users.get(user)
            if view is None or view.map is None:
                return None
            return view.map.copy(), view.map_version

    def frame(self) -> dict:
        """What the page draws, every user, as plain JSON-ready data."""
        with self._lock:
            return {
                "stamp": time.time(),
                "daemon_alive": self.daemon_alive,
                "cell_m": self.cell_m,
                "users": {u: self._user_frame(v) for u, v in sorted(self.users.items())},
            }

    def _user_frame(self, v: UserView) -> dict:
        h, w = v.map.shape if v.map is not None else (0, 0)
        return {
            "map": {"height": h, "width": w, "seq": v.map_seq, "version": v.map_version},
            "path": [list(rc) for rc in v.path.cells] if v.path is not None else [],
            "pose": _pose(v.pose),
            "goal": self._goal(v),
            "belt": _belt(v.belt),
            "status": _status(v.status),
            "cues": [{"text": c.text, "kind": c.kind, "stamp": c.stamp} for c in v.cues],
            "latency_ms": v.latency_ms,
            "messages": v.messages,
        }

    def _goal(self, v: UserView) -> dict | None:
        """The goal in metres where it can be placed on the map; its name otherwise."""
        if v.goal is None:
            return None
        target = v.goal.target
        if isinstance(target, GoalMetres):
            return {"x": target.x, "y": target.y}
        if isinstance(target, GoalCell):
            h = v.map.shape[0] if v.map is not None else (v.path.height if v.path else 0)
            if not h:
                return None
            return {
                "x": (target.col + 0.5) * self.cell_m,
                "y": (h - target.row - 0.5) * self.cell_m,
            }
        return {"name": target.name}


def _pose(p: Pose | None) -> dict | None:
    return None if p is None else {"x": p.x, "y": p.y, "heading": p.heading, "stamp": p.stamp}


def _belt(b: BeltPattern | None) -> dict | None:
    if b is None:
        return None
    return {
        "kind": str(b.kind), "motors": list(b.motors), "period_ms": b.period_ms, "seq": b.seq,
        "map_seq": b.map_seq,  # the map it was decided on: a belt behind the map shows here
    }  # fmt: skip


def _status(s: NavStatus | None) -> dict | None:
    if s is None:
        return None
    return {
        "state": str(s.state),
        "code": str(s.code),
        "reason": s.reason,
        "distance_m": s.distance_m,
        "replans": s.replans,
        "backend": s.backend,
        "paused": s.paused,
    }
