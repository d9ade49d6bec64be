"""The one way to open a zenoh session, and to declare anything on it from the topic table.

``open_session(settings)`` is where every guidebelt process opens its zenoh session: the
daemon, the drivers, the simulator and the command line build a ``ZenohSettings`` and call
it, so they agree on what scouting means. The ``declare_*``, ``put``, ``get`` and ``reply``
helpers take a ``Topic`` (``protocol.topics``) and a user, and apply the topic's QoS, so no
caller spells a key or chooses a congestion policy of its own.
"""

from __future__ import annotations

import json
from collections.abc import Callable
from typing import Any

import zenoh
from zenoh.handlers import Callback

from .access import WORKER, access_control, identities_for
from .settings import ZenohSettings, loopback
from .topics import WORKER_ALIVE, Kind, Topic

__all__ = [
    "ZenohSettings", "alive", "declare_publisher", "declare_queryable", "declare_subscriber",
    "declare_token", "declare_worker_token", "get", "loopback", "open_router", "open_session",
    "put", "reply", "watch_liveliness", "watch_workers",
]  # fmt: skip


def open_session(settings: ZenohSettings) -> zenoh.Session:
    return zenoh.open(zenoh.Config.from_json5(settings.to_json5()))


def router_config(settings: ZenohSettings, private: str) -> zenoh.Config:
    """The daemon's config as a zenoh *router* (``workers = N``: it forwards between the
    nodes and its worker processes), listening on the workers' ``private`` endpoint too; with
    access rules, the workers' among them (``access.WORKER``)."""
    raw = json.loads(settings.to_json5())
    raw["mode"] = "router"
    raw["listen"]["endpoints"] = [*raw["listen"]["endpoints"], private]
    if settings.access is not None:
        nodes = identities_for(settings.access.users, settings.access.services)
        raw["access_control"] = access_control([*nodes, WORKER])
    return zenoh.Config.from_json5(json.dumps(raw))


def open_router(settings: ZenohSettings, private: str) -> zenoh.Session:
    return zenoh.open(router_config(settings, private))


def _send_qos(topic: Topic) -> dict[str, Any]:
    """The topic's QoS as the keyword arguments of ``put``, ``get`` and ``reply``."""
    q = topic.qos
    return {
        "congestion_control": getattr(zenoh.CongestionControl, q.congestion.name),
        "priority": getattr(zenoh.Priority, q.priority.name),
        "express": q.express,
    }


def _expect(topic: Topic, kind: Kind) -> None:
    if topic.kind is not kind:
        raise ValueError(f"{topic.name} is a {topic.kind}, not a {kind}")


def declare_publisher(session: zenoh.Session, topic: Topic, user: str | None) -> zenoh.Publisher:
    _expect(topic, Kind.PUBSUB)
    return session.declare_publisher(
        topic.key(user),
        reliability=getattr(zenoh.Reliability, topic.qos.reliability.name),
        **_send_qos(topic),
    )


def declare_subscriber(
    session: zenoh.Session, topic: Topic, handler: Any, user: str | None = None
) -> zenoh.Subscriber:
    """Subscribe to one user's ``topic``, or every user's when ``user`` is None."""
    _expect(topic, Kind.PUBSUB)
    return session.declare_subscriber(topic.selector(user), handler)


def declare_queryable(
    session: zenoh.Session, topic: Topic, handler: Any, user: str | None = None
) -> zenoh.Queryable:
    """Answer ``topic`` for one user, or for every user when ``user`` is None."""
    _expect(topic, Kind.QUERYABLE)
    return session.declare_queryable(topic.selector(user), handler)


def put(session: zenoh.Session, topic: Topic, user: str | None, payload: bytes) -> None:
    """One publication without a declared publisher (a CLI's single goal), same QoS."""
    _expect(topic, Kind.PUBSUB)
    session.put(topic.key(user), payload, **_send_qos(topic))


def get(
    session: zenoh.Session,
    topic: Topic,
    user: str | None = None,
    handler: Any = None,
    timeout: float = 2.0,
) -> Any:
    """Query ``topic`` of one user (every user when None); zenoh's ``get`` result."""
    _expect(topic, Kind.QUERYABLE)
    return session.get(topic.selector(user), handler, timeout=timeout, **_send_qos(topic))


def reply(query: zenoh.Query, topic: Topic, user: str | None, payload: bytes) -> None:
    _expect(topic, Kind.QUERYABLE)
    # A reply travels with the query's congestion control and priority (zenoh 1.10 ignores,
    # and deprecates, setting them here); ``get`` above sets them from the same row.
    query.reply(topic.key(user), payload, express=topic.qos.express)


def declare_token(session: zenoh.Session, topic: Topic) -> zenoh.LivelinessToken:
    _expect(topic, Kind.LIVELINESS)
    return session.liveliness().declare_token(topic.key())


def declare_worker_token(session: zenoh.Session, index: int, pid: int) -> zenoh.LivelinessToken:
    """A worker process's token (``WORKER_ALIVE``): it goes when the worker's session does,
    however the worker died or lost its link."""
    return session.liveliness().declare_token(f"{WORKER_ALIVE.key()}/{index}/{pid}")


def watch_workers(
    session: zenoh.Session, on_change: Callable[[int, int, bool], None]
) -> zenoh.Subscriber:
    """``on_change(index, pid, alive)`` for every worker token that appears or goes."""

    def seen(sample: zenoh.Sample) -> None:
        parts = str(sample.key_expr).rsplit("/", 2)
        try:
            index, pid = int(parts[-2]), int(parts[-1])
        except (ValueError, IndexError):
            return  # not a worker's token: the router's rules let no one else declare one
        on_change(index, pid, sample.kind == zenoh.SampleKind.PUT)

    return session.liveliness().declare_subscriber(
        f"{WORKER_ALIVE.key()}/**", Callback(seen, indirect=False), history=True
    )


def watch_liveliness(
    session: zenoh.Session, topic: Topic, on_change: Callable[[zenoh.Sample], None]
) -> zenoh.Subscriber:
    """``on_change`` for every token of ``topic`` that appears (PUT) or goes (DELETE),
    starting with those alive now."""
    _expect(topic, Kind.LIVELINESS)
    return session.liveliness().declare_subscriber(topic.key(), on_change, history=True)


def alive(session: zenoh.Session, topic: Topic, timeout: float = 2.0) -> list[zenoh.Reply]:
    """The tokens of ``topic`` alive now."""
    _expect(topic, Kind.LIVELINESS)
    return list(session.liveliness().get(topic.key(), timeout=timeout))
