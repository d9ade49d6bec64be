"""What goes into one step of a user's session, and what comes out of it."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from protocol.messages import (
    BeltButton,
    BeltPattern,
    Goal,
    MapDelta,
    MapSnapshot,
    NavPath,
    NavStatus,
    Pose,
    Proximity,
    UserSettings,
    VoiceCue,
)

from .outcomes import Rejection


@dataclass
class Inbox:
    """What arrived for one user since the last step (filled on the loop thread)."""

    rejections: list[Rejection] = field(default_factory=list)
    deltas: list[MapDelta] = field(default_factory=list)
    snapshot: MapSnapshot | None = None
    snapshot_failed: bool = False
    goal: Goal | None = None
    pose: Pose | None = None
    tick: bool = False
    """Step even with nothing new: notices a pose that has gone stale."""
    buttons: list[BeltButton] = field(default_factory=list)
    settings: UserSettings | None = None
    """A change the user asked for on their own ``settings/set`` key."""
    battery_v: float | None = None
    """The belt's battery, from its latest health."""
    pose_received: float | None = None
    """When the daemon received ``pose`` (its own clock, seconds since the epoch): a pose is
    stale by this, never by how long the daemon took to get round to it. None: at ``now``."""
    taken_at: float | None = None
    """When the step's inputs were taken from the inbox (daemon clock). None: at ``now``."""
    overloaded: bool = False
    """The daemon is shedding this user: keep the map, goal and pose, guide nobody."""
    daemon_behind: bool = False
    """The daemon's loop is late on its inputs: a pose gone missing is said as overload."""
    pose_unread: bool = False
    """A newer pose reached the daemon than any it has read for this user (still queued on
    its loop, or dropped while the user was shed): a pose missing now is the daemon's doing."""
    proximity: Proximity | None = None
    """The mapper's latest nearest-obstacle report (the latest wins)."""

    def urgent(self) -> bool:
        """Inputs that step the user at once; a pose alone (or a tick) may wait its turn."""
        return bool(
            self.rejections
            or self.deltas
            or self.snapshot
            or self.snapshot_failed
            or self.goal
            or self.buttons
            or self.settings
            or self.proximity  # the belt's safety input: never waits for a pose's turn
        )

    def __bool__(self) -> bool:
        return self.urgent() or self.pose is not None or self.tick or self.battery_v is not None


@dataclass
class StepOutput:
    """Messages to publish, in order: belt, voice, path, status."""

    belt: list[BeltPattern] = field(default_factory=list)
    voice: list[VoiceCue] = field(default_factory=list)
    path_cells: np.ndarray | None = None
    """The path as planned; ``path()`` makes the message, after the belt is on its way."""
    path_meta: dict = field(default_factory=dict)
    statuses: list[NavStatus] = field(default_factory=list)
    want_snapshot: bool = False
    settings: UserSettings | None = None
    """The user's settings changed (a button, or ``settings/set``): to store and publish."""

    def path(self) -> NavPath | None:
        if self.path_cells is None:
            return None
        # Built by the daemon from the planner's own cells: no need to validate them again.
        return NavPath.model_construct(
            cells=[tuple(rc) for rc in self.path_cells.tolist()], **self.path_meta
        )
