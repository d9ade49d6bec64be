"""Shorthands for concrete keys, derived from the topic table (``protocol.topics``).

The table is the only place a key is spelled; these names remain for code that wants a
key string, e.g. ``keys.belt("ann")`` for a publication the daemon's bridge looks up in
the table again to find its QoS.
"""

from __future__ import annotations

from . import topics as T
from .topics import ROOT, USER_RE, check_user, user_of

__all__ = [
    "ALIVE", "HEALTH", "ROOT", "USER_RE", "belt", "belt_health", "check_user", "goal",
    "map_delta", "map_snapshot", "map_source", "path", "pose", "rfid_stats", "status",
    "user_of", "voice",
]  # fmt: skip

HEALTH = T.HEALTH.key()
ALIVE = T.ALIVE.key()

map_delta = T.MAP_DELTA.key
map_snapshot = T.MAP_SNAPSHOT.key
map_source = T.MAP_SOURCE.key
pose = T.POSE.key
goal = T.GOAL.key
path = T.PATH.key
status = T.STATUS.key
belt = T.BELT.key
belt_health = T.BELT_HEALTH.key
voice = T.VOICE.key
rfid_stats = T.RFID_STATS.key
