"""The wire contract: pydantic v2 models, the single source of truth for every message.

Every model forbids unknown fields and is frozen, so a message is either valid whole or
rejected whole. JSON on the wire except map deltas and snapshots (see ``codec.py``).
Units: metres, radians (0 = east, counter-clockwise), seconds since the Unix epoch.
"""

from __future__ import annotations

from enum import StrEnum
from typing import Annotated, Literal

from pydantic import BaseModel, ConfigDict, Field

MOTORS = ("front", "right", "back", "left")
"""Belt motor order, clockwise from the front, in every message and frame."""

Intensity = Annotated[int, Field(ge=0, le=255)]


class Message(BaseModel):
    model_config = ConfigDict(extra="forbid", frozen=True, strict=False)


class Pose(Message):
    x: float = Field(allow_inf_nan=False, description="metres east of the map origin")
    y: float = Field(allow_inf_nan=False, description="metres north of the map origin")
    heading: float = Field(allow_inf_nan=False, description="radians, 0 = east, CCW positive")
    stamp: float = Field(ge=0, allow_inf_nan=False, description="seconds since the Unix epoch")
    quality: float = Field(default=1.0, ge=0.0, le=1.0, description="1 = exact (sim, LF tag)")


class GoalCell(Message):
    kind: Literal["cell"] = "cell"
    row: int = Field(ge=0)
    col: int = Field(ge=0)


class GoalMetres(Message):
    kind: Literal["metres"] = "metres"
    x: float = Field(allow_inf_nan=False)
    y: float = Field(allow_inf_nan=False)


class GoalLandmark(Message):
    kind: Literal["landmark"] = "landmark"
    name: str = Field(min_length=1, max_length=64)


class Goal(Message):
    target: GoalCell | GoalMetres | GoalLandmark = Field(discriminator="kind")
    stamp: float = Field(ge=0, allow_inf_nan=False)


class PatternKind(StrEnum):
    GUIDE = "guide"  # direction to the next turning point
    ARRIVED = "arrived"
    STOP = "stop"
    REROUTE = "reroute"
    NO_PATH = "no_path"
    TURN_AROUND = "turn_around"
    WAIT = "wait"
    OFF = "off"


class BeltPattern(Message):
    seq: int = Field(ge=0, lt=2**32)
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
    stamp: float = Field(ge=0, allow_inf_nan=False)


class CuePriority(StrEnum):
    SAFETY = "safety"  # spoken at once, pre-empts routine cues
    ROUTINE = "routine"  # rate limited


class VoiceCue(Message):
    text: str = Field(min_length=1, max_length=300)
    lang: Literal["en", "es"] = "en"
    priority: CuePriority = CuePriority.ROUTINE
    kind: str = Field(min_length=1, max_length=32, description="e.g. direction, arrived, stop")
    stamp: float = Field(ge=0, allow_inf_nan=False)


class NavState(StrEnum):
    IDLE = "idle"
    PLANNING = "planning"
    GUIDING = "guiding"
    REROUTING = "rerouting"
    ARRIVED = "arrived"
    NO_PATH = "no_path"
    STALE = "stale"
    ERROR = "error"


class NavStatus(Message):
    state: NavState
    reason: str = ""
    stamp: float = Field(ge=0, allow_inf_nan=False)
    distance_m: float | None = Field(default=None, ge=0)
    rejected: int = Field(default=0, ge=0, description="messages rejected for this user so far")
    backend: str = ""


class Health(Message):
    daemon_id: str
    uptime_s: float = Field(ge=0)
    users: list[str]
    backend: str
    rejected: int = Field(ge=0)
    stamp: float = Field(ge=0)
