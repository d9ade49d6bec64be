"""The wire in one table: every zenoh key guidebelt uses, its message, its parties and QoS.

Everything per user lives under ``guidebelt/<user>/…``; daemon-wide keys under
``guidebelt/@daemon/…`` (``@`` cannot start a user name, so the two never clash). Every
publisher, subscriber, queryable, query and liveliness token in the product is declared
from a ``Topic`` of ``TOPICS`` (through ``protocol.session``), so a key's leaf, its message
model and its QoS are written here and nowhere else.

QoS is chosen for a safety system. What steers or stops the user (belt patterns, status,
voice cues, goals, map deltas) is never dropped on a busy link: congestion control BLOCK,
at a priority above bulk data so it overtakes a snapshot on the same link; the belt
pattern, the last hop before the motors, goes at REAL_TIME, ahead of everything. Poses are
latest-wins (each supersedes the one before), so a full queue may drop one, but the queue
is their own, never the must-arrive messages' (``LATEST_POSE``); so may paths,
belt health and RFID stats. Everything a step of the guidance loop waits for is
``express`` (sent at once, not batched), so map change to belt carries no batching delay.
Reliability is RELIABLE throughout: the wearable's links are TCP (or loopback), where best
effort buys nothing, and a lost sample must show up as a gap, not vanish.

This module is plain data and imports no zenoh: the QoS words below are mapped onto
zenoh's enums by ``protocol.session``, so the table (and ``guidebelt schema``) can be read
on a machine without zenoh.
"""

from __future__ import annotations

import re
from dataclasses import dataclass, field
from enum import StrEnum

from .messages import (
    BeltButton,
    BeltHealth,
    BeltPattern,
    Goal,
    Health,
    MapDelta,
    MapSnapshot,
    Message,
    NavPath,
    NavStatus,
    Pose,
    Proximity,
    RfidStats,
    UserSettings,
    VoiceCue,
)

ROOT = "guidebelt"
DAEMON_SCOPE = "@daemon"
USER_RE = re.compile(r"^[a-z0-9][a-z0-9_-]{0,31}$")


def check_user(user: str) -> str:
    if not USER_RE.match(user):
        raise ValueError(f"bad user name {user!r}: use [a-z0-9_-], 1..32 chars, no leading _ or -")
    return user


def user_of(key: object) -> str:
    """The user segment of a per-user key (``str(key)``, so a zenoh ``KeyExpr`` will do)."""
    parts = str(key).split("/")
    if len(parts) < 3 or parts[0] != ROOT:
        raise ValueError(f"not a guidebelt key: {key!r}")
    return check_user(parts[1])


class Kind(StrEnum):
    PUBSUB = "publish/subscribe"
    QUERYABLE = "queryable"
    LIVELINESS = "liveliness token"


class Reliability(StrEnum):
    RELIABLE = "reliable"
    BEST_EFFORT = "best_effort"


class Congestion(StrEnum):
    BLOCK = "block"  # wait for the queue: never lost silently
    DROP = "drop"  # a full queue loses it: only for latest-wins data


class Priority(StrEnum):
    """zenoh's priorities, highest first (same names as ``zenoh.Priority``)."""

    REAL_TIME = "real_time"
    INTERACTIVE_HIGH = "interactive_high"
    INTERACTIVE_LOW = "interactive_low"
    DATA_HIGH = "data_high"
    DATA = "data"
    DATA_LOW = "data_low"
    BACKGROUND = "background"


@dataclass(frozen=True)
class QoS:
    reliability: Reliability = Reliability.RELIABLE
    congestion: Congestion = Congestion.BLOCK
    priority: Priority = Priority.DATA
    express: bool = False


# The QoS classes the table uses.
MUST_ARRIVE = QoS(priority=Priority.INTERACTIVE_HIGH, express=True)
"""Steers or stops the user: blocks rather than drops, ahead of bulk data, not batched."""
LATEST_WINS = QoS(congestion=Congestion.DROP, express=True)
"""Superseded by the next sample: dropping one on a full queue is harmless."""
BULK = QoS(priority=Priority.DATA_LOW)
"""Large and rare (snapshots): must arrive, but behind everything that steers."""
LATEST_POSE = QoS(congestion=Congestion.DROP, priority=Priority.INTERACTIVE_LOW, express=True)
"""Poses: latest-wins, so DROP, but in a queue of their own, one priority below the
must-arrive messages. zenoh drops a DROP sample that finds its priority's queue full for
``wait_before_drop`` (1 ms); sharing the must-arrive queue, a pose put just after a map delta
and a goal found it full whenever zenoh's sending thread got no CPU for a millisecond, and a
user's only pose was lost (6 of 40 rounds of a one-pose test on a busy 2-core VM). In their
own queue, a pose is dropped only behind earlier poses still unsent."""


class Role(StrEnum):
    """Who a node is, as its certificate says (``protocol.access``): what it may send and
    receive on each key is read from the table's ``writers`` and ``readers`` below."""

    DAEMON = "daemon"
    USER = "user"  # a user's phone or client: that user's goals and settings, status back
    BELT = "belt"  # a user's belt driver
    VOICE = "voice"  # a user's voice driver
    RFID = "rfid"  # a user's RFID localiser
    MAPPER = "mapper"  # the map source, every user's map
    SIM = "sim"  # the simulator: mapper, localiser, user and belt for every user
    MONITOR = "monitor"  # read-only tools: view, recorder, `guidebelt status`, health


PER_USER_ROLES = frozenset({Role.USER, Role.BELT, Role.VOICE, Role.RFID})
"""Roles bound to one user: their keys are that user's only."""


@dataclass(frozen=True)
class Topic:
    """One row of the wire: a key, what travels on it, who sends and who listens, and how."""

    name: str
    leaf: str
    """The key below ``guidebelt/<user>/`` (or ``guidebelt/@daemon/`` when not per user)."""
    model: type[Message] | None
    """The message on it (a reply's, for a queryable); None for a liveliness token."""
    kind: Kind
    producer: str
    """Who publishes, answers the queries, or holds the token."""
    consumers: str
    qos: QoS = field(default=MUST_ARRIVE)
    per_user: bool = True
    writers: frozenset[Role] = frozenset({Role.DAEMON})
    """Roles that may publish on it, answer its queries, or hold its token."""
    readers: frozenset[Role] = frozenset()
    """Roles that may subscribe to it, query it, or watch its token."""

    def key(self, user: str | None = None) -> str:
        """The concrete key, e.g. ``POSE.key("ann")`` → ``guidebelt/ann/pose``."""
        if not self.per_user:
            if user is not None:
                raise ValueError(f"{self.name} is daemon-wide, not per user")
            return f"{ROOT}/{DAEMON_SCOPE}/{self.leaf}"
        if user is None:
            raise ValueError(f"{self.name} is per user: name the user")
        return f"{ROOT}/{check_user(user)}/{self.leaf}"

    def any_user(self) -> str:
        """The wildcard over every user, e.g. ``guidebelt/*/pose``."""
        if not self.per_user:
            raise ValueError(f"{self.name} is daemon-wide, not per user")
        return f"{ROOT}/*/{self.leaf}"

    def selector(self, user: str | None) -> str:
        """One user's key, or every user's when ``user`` is None (or ``"*"``)."""
        if not self.per_user:
            return self.key()
        return self.any_user() if user in (None, "*") else self.key(user)

    def user_of(self, key: object) -> str:
        """The user of a concrete key of this topic; ValueError for any other key."""
        if not (self.per_user and self.matches(key)):
            raise ValueError(f"{key!r} is not a per-user key of {self.name}")
        return user_of(key)

    def matches(self, key: object) -> bool:
        """Whether a concrete key is this topic's (for any user)."""
        parts = str(key).split("/", 2)
        if len(parts) != 3 or parts[0] != ROOT or parts[2] != self.leaf:
            return False
        return (parts[1] == DAEMON_SCOPE) != self.per_user


def _t(
    name: str,
    leaf: str,
    model,
    kind: Kind,
    producer: str,
    consumers: str,
    by: tuple[Role, ...] = (Role.DAEMON,),
    to: tuple[Role, ...] = (),
    **kw,
) -> Topic:
    return Topic(
        name, leaf, model, kind, producer, consumers, writers=frozenset(by), readers=frozenset(to),
        **kw,
    )  # fmt: skip


PS, Q, LV = Kind.PUBSUB, Kind.QUERYABLE, Kind.LIVELINESS
D, U, B, V, R, M, S, MON = (
    Role.DAEMON, Role.USER, Role.BELT, Role.VOICE, Role.RFID, Role.MAPPER, Role.SIM, Role.MONITOR,
)  # fmt: skip

MAP_DELTA = _t("map_delta", "map/delta", MapDelta, PS, "mapper / sim", "daemon",
               by=(M, S), to=(D,))
MAP_SNAPSHOT = _t("map_snapshot", "map/snapshot", MapSnapshot, Q, "daemon", "view, tools",
                  to=(U, S, MON), qos=BULK)
MAP_SOURCE = _t("map_source", "map/source", MapSnapshot, Q, "mapper / sim",
                "daemon (after a sequence gap)", by=(M, S), to=(D,), qos=BULK)
POSE = _t("pose", "pose", Pose, PS, "localiser / RFID node / sim", "daemon", by=(R, S), to=(D,),
          qos=LATEST_POSE)
GOAL = _t("goal", "goal", Goal, PS, "client / phone / CLI / mapper (the target it sees)",
          "daemon", by=(U, S, M), to=(D,))
PATH = _t("path", "path", NavPath, PS, "daemon", "sim, view, recorder", to=(U, S, MON),
          qos=LATEST_WINS)
STATUS = _t("status", "status", NavStatus, PS, "daemon", "client, CLI, sim, recorder",
            to=(U, S, MON))
STATUS_QUERY = _t("status_query", "status", NavStatus, Q, "daemon", "CLI (`guidebelt status`)",
                  to=(U, S, MON))
BELT = _t("belt", "belt", BeltPattern, PS, "daemon", "belt driver, sim, recorder",
          to=(B, S, MON), qos=QoS(priority=Priority.REAL_TIME, express=True))
BELT_HEALTH = _t("belt_health", "belt/health", BeltHealth, PS, "belt driver", "view, tools",
                 by=(B, S), to=(D, MON), qos=LATEST_WINS)
BELT_BUTTON = _t("belt_button", "belt/button", BeltButton, PS, "belt driver", "daemon",
                 by=(B, S), to=(D,))
SETTINGS_SET = _t("settings_set", "settings/set", UserSettings, PS, "the user's client / phone",
                  "daemon (on this user's key only)", by=(U, S), to=(D,))
SETTINGS = _t("settings", "settings", UserSettings, PS, "daemon",
              "belt driver (intensity), client", to=(B, U, S, MON))
SETTINGS_QUERY = _t("settings_query", "settings", UserSettings, Q, "daemon",
                    "belt driver (at start), client", to=(B, U, S, MON))
VOICE = _t("voice", "voice", VoiceCue, PS, "daemon", "voice driver, recorder",
           to=(V, S, MON))
RFID_STATS = _t("rfid_stats", "rfid/stats", RfidStats, PS, "RFID node", "view, tools",
                by=(R, S), to=(MON,), qos=LATEST_WINS)
PROXIMITY = _t("proximity", "proximity", Proximity, PS, "mapper", "daemon (STOP before contact)",
               by=(M, S), to=(D,))
HEALTH = _t("health", "health", Health, Q, "daemon", "CLI, monitoring", to=(S, MON),
            per_user=False)
ALIVE = _t("alive", "alive", None, LV, "daemon", "belt driver (STOP when it goes)",
           to=(U, B, V, R, M, S, MON), per_user=False)
WORKER_ALIVE = _t("worker_alive", "workers", None, LV, "each of the daemon's worker processes",
                  "the daemon's parent (stops the worker's users when it goes)", per_user=False)
"""One token per worker process (``workers = N``), below this key: ``…/workers/<index>/<pid>``
(``session.declare_worker_token``). Only the daemon's parent, the router, watches them."""

TOPICS: tuple[Topic, ...] = (
    MAP_DELTA, MAP_SNAPSHOT, MAP_SOURCE, POSE, GOAL, PATH, STATUS, STATUS_QUERY,
    BELT, BELT_HEALTH, BELT_BUTTON, SETTINGS_SET, SETTINGS, SETTINGS_QUERY, VOICE, RFID_STATS,
    PROXIMITY, HEALTH, ALIVE, WORKER_ALIVE,
)  # fmt: skip


def topic_of(key: object, kind: Kind = Kind.PUBSUB) -> Topic:
    """The ``kind`` of topic a concrete key belongs to; ValueError for a key not in the table."""
    for topic in TOPICS:
        if topic.kind is kind and topic.matches(key):
            return topic
    raise ValueError(f"no {kind} topic has the key {key!r}")


def wire_models() -> tuple[type[Message], ...]:
    """Every message that travels on some key, each once, in table order."""
    return tuple(dict.fromkeys(t.model for t in TOPICS if t.model is not None))
