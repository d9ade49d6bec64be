"""The wire contract: pydantic v2 models, the single source of truth for every message.

Every model forbids unknown fields and is frozen, so a message is either valid whole or
rejected whole. JSON on the wire except map deltas and snapshots (see ``codec.py``).
Units: metres, radians (0 = east, counter-clockwise), seconds since the Unix epoch.
"""

from __future__ import annotations

from enum import StrEnum
from typing import Literal

from pydantic import Field

from .map_messages import (  # the map messages are wire messages like the others
    MAX_DELTA_CELLS,
    MAX_EPOCH,
    OCCUPANCY_VALUES,
    Epoch,
    MapDelta,
    MapSnapshot,
)
from .wire_types import (
    MAX_SIDE,
    MAX_STAMP,
    MOTORS,
    Amount,
    Count,
    Intensity,
    Message,
    Metres,
    Radians,
    Stamp,
)

__all__ = [
    "MAX_DELTA_CELLS", "MAX_EPOCH", "MAX_SIDE", "MAX_STAMP", "MOTORS", "OCCUPANCY_VALUES",
    "Amount", "BeltButton", "BeltHealth", "BeltPattern", "Count", "CuePriority", "Epoch", "Goal",
    "GoalCell", "GoalLandmark", "GoalMetres", "Health", "Intensity", "MapDelta", "MapSnapshot",
    "Message", "Metres", "NavPath", "NavState", "NavStatus", "PatternKind", "Pose", "Proximity",
    "Radians", "RfidStats", "Stamp", "StatusCode", "UserSettings", "VoiceCue",
]  # fmt: skip

class Pose(Message):
    x: Metres = Field(description="metres east of the map origin")
    y: Metres = Field(description="metres north of the map origin")
    heading: Radians = Field(description="radians, 0 = east, CCW positive")
    stamp: Stamp = Field(description="seconds since the Unix epoch")
    quality: float = Field(default=1.0, ge=0.0, le=1.0, description="1 = exact (sim, LF tag)")
    sigma_m: float | None = Field(
        default=None,
        ge=0.0,
        le=100.0,
        allow_inf_nan=False,
        description="1-sigma position uncertainty, metres (None: derived from quality)",
    )


class GoalCell(Message):
    kind: Literal["cell"] = "cell"
    row: int = Field(ge=0, lt=MAX_SIDE)
    col: int = Field(ge=0, lt=MAX_SIDE)


class GoalMetres(Message):
    kind: Literal["metres"] = "metres"
    x: Metres
    y: Metres


class GoalLandmark(Message):
    kind: Literal["landmark"] = "landmark"
    name: str = Field(min_length=1, max_length=64)


class Goal(Message):
    target: GoalCell | GoalMetres | GoalLandmark = Field(discriminator="kind")
    stamp: Stamp


class PatternKind(StrEnum):
    GUIDE = "guide"  # direction to the next turning point
    ARRIVED = "arrived"
    STOP = "stop"
    REROUTE = "reroute"
    NO_PATH = "no_path"
    TURN_AROUND = "turn_around"
    WAIT = "wait"
    OFF = "off"
    PAUSED = "paused"  # the user paused guidance (belt button): one tap, then quiet
    RESUMED = "resumed"  # the user resumed it: a short three-motor tap, then GUIDE
    OBSTACLE = "obstacle"  # not guiding: the nearest obstacle's side, fast on one motor
    LOOK = "look"  # no goal and the camera does not see the target: turn in place and look


class BeltPattern(Message):
    seq: int = Field(ge=0, lt=2**32)
    map_seq: int = Field(
        ge=-1,
        lt=2**32,
        description="the map version the pattern was decided on: the last map delta sequence "
        "(of the map source's current epoch; a snapshot counts as its seq) the user's step had "
        "applied when it built the pattern, as NavPath.map_seq; -1 while the user has no map of "
        "that epoch yet. Required: every pattern comes from a user's step, which always has "
        "this, so a pattern without it is refused whole like any other malformed message",
    )
    kind: PatternKind
    motors: tuple[Intensity, Intensity, Intensity, Intensity] = Field(
        description="intensity 0..255 of (front, right, back, left)"
    )
    period_ms: int = Field(
        default=0, ge=0, le=5000, description="0 = steady; else on/off pulse period"
    )
    ttl_ms: int = Field(
        ge=50, le=5000, description="the belt goes silent this long after the last pattern"
    )
    stamp: Stamp


class BeltHealth(Message):
    """The belt driver's view of its serial link and of the firmware's own counters."""

    port: str
    connected: bool
    belt_state: str = Field(description="boot, active, idle, watchdog, stopped or unknown")
    frames_sent: Count
    acks: Count
    refused: Count = Field(description="acks saying the belt refused a frame's content")
    dropped: Count = Field(description="frames not written: port full or gone")
    reconnects: Count
    rx_errors: Count = Field(description="bad frames from the belt seen by the driver")
    belt_crc_errors: Count = Field(description="the firmware's counters, from heartbeats")
    belt_oversized: Count
    belt_truncated: Count
    belt_malformed: Count
    watchdog_trips: Count
    latency_ms: Amount | None = Field(default=None, description="median ack round trip")
    heartbeat_age_s: Amount | None = None
    battery_v: float | None = Field(
        default=None, ge=0, le=20, description="the belt's battery, read by the Nano"
    )
    intensity: int | None = Field(
        default=None, ge=0, le=100, description="the intensity the firmware applies now"
    )
    presses: Count = Field(default=0, description="button presses published")
    presses_dropped: Count = Field(
        default=0, description="presses the belt gave up on (never acknowledged)"
    )
    stamp: Stamp


class BeltButton(Message):
    """A press of one of the belt's buttons, once per press (the driver drops repeats)."""

    press: int = Field(ge=1, lt=2**16, description="the belt's own press number")
    button: int = Field(ge=0, le=2, description="0 = D4, 1 = D7, 2 = D8 (PATTERNS.md)")
    kind: Literal["short", "long"]
    stamp: Stamp


class UserSettings(Message):
    """One user's settings that may change while walking: asked for on ``settings/set``
    (the user's own key only), applied and stored by the daemon, published on ``settings``.
    In a request a field left out (null) stays as it is; what the daemon publishes has every
    field."""

    intensity: int | None = Field(
        default=None, ge=0, le=100, description="belt intensity: 0 = the 40 % floor, 100 = full"
    )
    voice: Literal["companion", "sole"] | None = Field(
        default=None, description="companion: beside the belt; sole: the voice guides alone"
    )
    wording: Literal["clock", "sides"] | None = Field(
        default=None, description="turn to 2 o'clock, or turn slightly right"
    )
    units: Literal["metric", "imperial"] | None = Field(
        default=None, description="distances in metres or in feet"
    )
    stamp: Stamp


class CuePriority(StrEnum):
    SAFETY = "safety"  # spoken at once, pre-empts routine cues
    ROUTINE = "routine"  # rate limited


class VoiceCue(Message):
    text: str = Field(min_length=1, max_length=300)
    lang: Literal["en", "es"] = "en"
    priority: CuePriority = CuePriority.ROUTINE
    kind: str = Field(min_length=1, max_length=32, description="e.g. direction, arrived, stop")
    stamp: Stamp


class NavState(StrEnum):
    IDLE = "idle"
    PLANNING = "planning"
    GUIDING = "guiding"
    REROUTING = "rerouting"
    ARRIVED = "arrived"
    NO_PATH = "no_path"
    STALE = "stale"
    ERROR = "error"


class StatusCode(StrEnum):
    """Why a status is what it is: ``NavStatus.code`` on the wire; OK ("") when all is well.

    A ``StrEnum`` compares equal to its string, so code that still passes plain strings
    keeps working, and the JSON on the wire is unchanged.
    """

    OK = ""
    # Undecodable or invalid messages, whatever key they came on (``codec.DecodeError``).
    MALFORMED = "malformed"
    WRONG_TYPE = "wrong_type"
    UNKNOWN_FIELD = "unknown_field"
    INVALID = "invalid"
    # Goals the planner cannot take.
    GOAL_OFF_MAP = "goal_off_map"
    GOAL_IN_OBSTACLE = "goal_in_obstacle"
    UNKNOWN_LANDMARK = "unknown_landmark"
    NO_PATH = "no_path"
    # Positions the daemon cannot trust.
    POSE_OFF_MAP = "pose_off_map"
    STALE_POSE = "stale_pose"
    POSE_UNCERTAIN = "pose_uncertain"
    """The pose's own uncertainty (``Pose.sigma_m`` / ``quality``) is past the daemon's limit."""
    # Map updates refused whole.
    OVERSIZED = "oversized"
    SHAPE_MISMATCH = "shape_mismatch"
    SEQUENCE_GAP = "sequence_gap"
    NEW_EPOCH = "new_epoch"
    """The map source restarted (a new epoch): the map is resynchronised from its snapshot."""
    OLD_EPOCH = "old_epoch"
    """A delta or snapshot of an epoch the source has left behind: refused."""
    # The daemon itself.
    TOO_MANY_USERS = "too_many_users"
    OVERLOADED = "overloaded"
    INTERNAL = "internal"
    SHUTDOWN = "shutdown"
    IDLE = "idle"
    RESTORED = "restored"
    """The daemon restarted and restored the session: it waits for a fresh pose."""


class NavStatus(Message):
    state: NavState
    reason: str = ""
    stamp: Stamp
    distance_m: Amount | None = Field(default=None, description="metres left")
    rejected: Count = Field(default=0, description="messages rejected for this user so far")
    backend: str = ""
    replans: Count = Field(default=0, description="times a new obstacle cut the path")
    code: StatusCode = Field(
        default=StatusCode.OK,
        description="machine-readable cause, e.g. goal_off_map, stale_pose; empty when all is well",
    )
    paused: bool = Field(default=False, description="the user paused guidance (belt button)")


class Health(Message):
    daemon_id: str
    uptime_s: Amount
    users: list[str]
    backend: str
    rejected: Count
    rejected_by_code: dict[str, int] = Field(
        default_factory=dict, max_length=64, description="refused inputs by status code"
    )
    log_lines_suppressed: Count = Field(
        default=0, description="bad-input log lines held back by the rate limit"
    )
    overloaded: list[str] = Field(
        default_factory=list, description="users not guided now: the daemon is at capacity"
    )
    lag_p95_ms: Amount = Field(
        default=0.0, description="input-to-belt delay of the guided users, last second"
    )
    stamp: Stamp


class RfidStats(Message):
    """The RFID node's reader and localiser counters, once a second."""

    accepted: Count = Field(description="reads of known tags")
    garbage: Count = Field(description="lines refused: not a read")
    checksum: Count = Field(description="lines refused: bad checksum")
    impossible_rssi: Count = Field(description="lines refused: RSSI out of range")
    unknown_tag: Count = Field(description="reads of tags not in the tag map")
    info: Count = Field(description="reader info lines (# …)")
    connected: bool
    connects: Count
    disconnects: Count
    poses: Count = Field(description="poses published so far")
    source: Literal["lf", "lf-hold", "uhf"] | None = Field(
        default=None, description="what the last pose came from"
    )
    quality: float | None = Field(default=None, ge=0, le=1)
    stamp: Stamp


class Proximity(Message):
    """The nearest obstacles in the mapper's latest frame: the belt's safety input.

    From the frame itself, not the merged map, so the daemon can stop the user before
    contact whatever the planner knows. Distances from the user to the obstacle's nearest
    edge; None when the frame shows no obstacle there.
    """

    ahead_m: Amount | None = Field(
        default=None,
        description="nearest obstacle in the walking corridor, in front of the user",
    )
    nearest_m: Amount | None = None
    bearing: float | None = Field(
        default=None,
        ge=-4.0,
        le=4.0,
        allow_inf_nan=False,
        description="of the nearest obstacle, radians from the heading, CCW positive (left)",
    )
    target_seen: bool | None = Field(
        default=None,
        description="a camera that looks for the target (seed 004's colour map): whether this "
        "frame saw it; None: this camera does not look for one",
    )
    frame_stamp: Stamp = Field(description="when the frame was taken")
    stamp: Stamp


class NavPath(Message):
    """The planned path of one user, from the cell of the pose it was planned for."""

    cells: list[tuple[int, int]] = Field(description="(row, col) from the user to the goal")
    cost: Count = Field(description="sum of 10/14 step costs")
    cell_m: float = Field(gt=0, le=100)
    height: int = Field(ge=1, le=MAX_SIDE)
    width: int = Field(ge=1, le=MAX_SIDE)
    pose_stamp: Stamp = Field(description="stamp of the pose this path starts from")
    stamp: Stamp
    map_seq: int = Field(
        default=-1, ge=-1, lt=2**32, description="last map delta this path reflects"
    )
