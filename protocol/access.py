"""Who may say what: zenoh access-control rules generated from the topic table.

Every node holds a certificate from the deployment's CA (``protocol.certificates``) whose
common name says who it is: ``user:ann`` (ann's phone), ``belt:ann``, ``voice:ann``,
``rfid:ann``, or a service bound to no user: ``mapper``, ``sim``, ``monitor``. The daemon is
the hub every other node connects to, so its zenoh session enforces the rules for all of
them, on what comes in from a node (ingress) and on what goes out to it (egress), with
everything not allowed denied:

- a node may publish on a key only if its role is among the topic's ``writers``, and
  subscribe only if among its ``readers`` (queryables: answer / query alike);
- a role bound to a user gets that user's keys only, so ``user:ann`` cannot put bob's goal
  nor subscribe to ``guidebelt/*/status``; a service gets every user's keys;
- the daemon's own declarations (its subscribers and queryables, all over every user) are
  announced to the nodes that need them to send there; they say nothing about any user.

The rules name zenoh's message kinds as its ``access_control`` config spells them
(``put``, ``declare_subscriber``, ``query``, ``reply``, ``declare_queryable``,
``liveliness_token``, ``liveliness_query``, ``declare_liveliness_subscriber``). zenoh grants
a message when an allowing key expression *includes* the message's, so a per-user rule on
``guidebelt/ann/status`` never covers a subscription to ``guidebelt/*/status``.
"""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass
from typing import Any

from .topics import PER_USER_ROLES, TOPICS, WORKER_ALIVE, Kind, Role, Topic, check_user

SERVICE_ROLES = (Role.MAPPER, Role.SIM, Role.MONITOR)
"""Roles not bound to a user (the daemon itself is the enforcer; its workers, below, are
the one way it is also a subject)."""
LOOPBACK_INTERFACES = ("lo",)
"""Where a worker's link may come from: the daemon's certificate is honoured on this host's
loopback only, so its key, were it copied off the machine, opens nothing."""


@dataclass(frozen=True)
class Identity:
    """One certificate's holder: a role, and for a per-user role its user."""

    role: Role
    user: str | None = None

    def __post_init__(self) -> None:
        if self.role in PER_USER_ROLES:
            if self.user is None:
                raise ValueError(f"role {self.role} is bound to a user: name one")
            check_user(self.user)
        elif self.user is not None:
            raise ValueError(f"role {self.role} is not bound to a user")

    @property
    def common_name(self) -> str:
        return f"{self.role}:{self.user}" if self.user else str(self.role)

    @property
    def stem(self) -> str:
        """The file name of its certificate, key and config (no ``:`` in file names)."""
        return f"{self.role}-{self.user}" if self.user else str(self.role)

    @classmethod
    def parse(cls, common_name: str) -> Identity:
        role, _, user = common_name.partition(":")
        try:
            return cls(Role(role), user or None)
        except ValueError as exc:
            raise ValueError(f"{common_name!r} is not a guidebelt identity: {exc}") from exc


def identities_for(users: Iterable[str], services: Iterable[Role]) -> list[Identity]:
    """Every per-user role for each user, then the services."""
    out = [Identity(role, user) for user in users for role in sorted(PER_USER_ROLES)]
    return out + [Identity(Role(s)) for s in services]


# The daemon's view: what a node with a role may send in (ingress) and be sent (egress).
_PUBSUB_WRITER = (("ingress", ("put",)), ("egress_daemon", ("declare_subscriber",)))
_PUBSUB_READER = (("ingress", ("declare_subscriber",)), ("egress", ("put",)))
_QUERY_ANSWERER = (("ingress", ("declare_queryable", "reply")), ("egress", ("query",)))
_QUERY_ASKER = (
    ("ingress", ("query",)),
    ("egress", ("reply",)),
    ("egress_daemon", ("declare_queryable",)),
)
_TOKEN_WATCHER = (
    ("ingress", ("declare_liveliness_subscriber", "liveliness_query")),
    ("egress", ("liveliness_token", "reply")),
)


def _grants(topic: Topic, role: Role) -> tuple[tuple[str, tuple[str, ...]], ...]:
    writes, reads = role in topic.writers, role in topic.readers
    if topic.kind is Kind.PUBSUB:
        return (_PUBSUB_WRITER if writes else ()) + (_PUBSUB_READER if reads else ())
    if topic.kind is Kind.QUERYABLE:
        return (_QUERY_ANSWERER if writes else ()) + (_QUERY_ASKER if reads else ())
    return _TOKEN_WATCHER if reads else ()


def _key(topic: Topic, who: Identity) -> str:
    if not topic.per_user:
        return topic.key()
    return topic.key(who.user) if who.user else topic.any_user()


def rules_for(who: Identity) -> list[dict[str, Any]]:
    """The allowing rules of one identity, merged by (flow, messages) over the table."""
    keys: dict[tuple[str, tuple[str, ...]], list[str]] = {}
    for topic in TOPICS:
        if who.role is Role.DAEMON and topic is WORKER_ALIVE:
            # A worker holds its own token, for its parent (the router itself) to watch.
            keys[("ingress", ("liveliness_token",))] = [f"{topic.key()}/**"]
            continue
        if who.role is Role.DAEMON and not topic.per_user:
            continue  # the parent alone answers health and holds the token, not a worker
        for flow, messages in _grants(topic, who.role):
            # The daemon declares over every user; announcing that leaks nothing of a user.
            key = topic.selector(None) if flow == "egress_daemon" else _key(topic, who)
            bucket = keys.setdefault((flow.removesuffix("_daemon"), messages), [])
            if key not in bucket:
                bucket.append(key)
    return [
        {
            "id": f"{who.common_name}/{flow}/{'+'.join(messages)}",
            "messages": list(messages),
            "flows": [flow],
            "permission": "allow",
            "key_exprs": key_exprs,
        }
        for (flow, messages), key_exprs in keys.items()
    ]


WORKER = Identity(Role.DAEMON)
"""A worker process of the daemon (``workers = N``): it holds the daemon's certificate and
connects to the parent's router, which enforces these rules. It may do on its link what the
table lets the daemon do for every user (subscribe to poses, goals and deltas, publish
belts, cues and statuses, answer status queries, ask the mapper for a snapshot) and no more:
not the daemon-wide health answer nor the liveliness token, which stay the parent's. It holds
its own token (``WORKER_ALIVE``), by which the parent knows it is gone."""


def access_control(identities: Iterable[Identity]) -> dict[str, Any]:
    """zenoh's ``access_control`` config for the daemon: deny all but the table's grants.
    Pass ``WORKER`` among ``identities`` for a daemon whose users are served by workers."""
    rules: list[dict[str, Any]] = []
    subjects: list[dict[str, Any]] = []
    policies: list[dict[str, Any]] = []
    seen: set[str] = set()
    for who in identities:
        if who.common_name in seen:
            continue
        seen.add(who.common_name)
        mine = rules_for(who)
        if not mine:
            continue
        rules += mine
        subject: dict[str, Any] = {"id": who.common_name, "cert_common_names": [who.common_name]}
        if who.role is Role.DAEMON:
            subject["interfaces"] = list(LOOPBACK_INTERFACES)
        subjects.append(subject)
        policies.append(
            {"id": who.common_name, "rules": [r["id"] for r in mine], "subjects": [who.common_name]}
        )
    return {
        "enabled": True,
        "default_permission": "deny",
        "rules": rules,
        "subjects": subjects,
        "policies": policies,
    }
