"""Zenoh key expressions: the only place they are spelled.

Everything per user lives under ``guidebelt/<user>/…``; daemon-wide keys under
``guidebelt/@daemon/…`` (``@`` cannot start a user name, so the two never clash).
"""

from __future__ import annotations

import re

ROOT = "guidebelt"
USER_RE = re.compile(r"^[a-z0-9][a-z0-9_-]{0,31}$")

HEALTH = f"{ROOT}/@daemon/health"
ALIVE = f"{ROOT}/@daemon/alive"


def check_user(user: str) -> str:
    if not USER_RE.match(user):
        raise ValueError(f"bad user name {user!r}: use [a-z0-9_-], 1..32 chars, no leading _ or -")
    return user


def _user_key(user: str, leaf: str) -> str:
    return f"{ROOT}/{check_user(user)}/{leaf}"


def map_delta(user: str) -> str:
    return _user_key(user, "map/delta")


def map_snapshot(user: str) -> str:
    return _user_key(user, "map/snapshot")


def map_source(user: str) -> str:
    """Queryable of the map's producer (mapper or sim): the daemon asks it for a snapshot
    when it sees a gap in the delta sequence. ``map_snapshot`` is the daemon's own map."""
    return _user_key(user, "map/source")


def pose(user: str) -> str:
    return _user_key(user, "pose")


def goal(user: str) -> str:
    return _user_key(user, "goal")


def path(user: str) -> str:
    return _user_key(user, "path")


def status(user: str) -> str:
    return _user_key(user, "status")


def belt(user: str) -> str:
    return _user_key(user, "belt")


def belt_health(user: str) -> str:
    """The belt driver's link health (``BeltHealth``), published by ``guidebelt belt``."""
    return _user_key(user, "belt/health")


def voice(user: str) -> str:
    return _user_key(user, "voice")


def rfid(user: str, leaf: str = "reads") -> str:
    return _user_key(user, f"rfid/{leaf}")


def any_user(leaf: str) -> str:
    """Wildcard over all users, e.g. ``any_user('pose')`` → ``guidebelt/*/pose``."""
    return f"{ROOT}/*/{leaf}"


def user_of(key: str) -> str:
    """The user segment of a per-user key."""
    parts = str(key).split("/")
    if len(parts) < 3 or parts[0] != ROOT:
        raise ValueError(f"not a guidebelt key: {key!r}")
    return check_user(parts[1])
