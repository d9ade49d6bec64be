"""What ``guidebelt certs`` writes: the CA, one certificate per node, and each node's config.

For every identity (``protocol.access``) three files named by its stem: ``<stem>.pem`` and
``<stem>.key`` (its certificate and key), ``<stem>.toml`` (the ``[zenoh]`` table guidebelt
reads: the daemon's goes into ``guidebelt.toml``, a driver's is passed as
``--zenoh-config``) and ``<stem>.json5`` (zenoh's own config, for a node not written in
guidebelt, e.g. a phone app on zenoh's Kotlin or C API). The daemon's table carries the
access rules; the others only connect to it.
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path

from .access import Identity, identities_for
from .certificates import KeyPair, issue, load_ca, make_ca
from .settings import AccessSettings, TlsSettings, ZenohSettings
from .topics import Role

DAEMON_STEM = "daemon"
DEFAULT_ENDPOINT = "tls/127.0.0.1:7447"
DEFAULT_HOSTS = ("localhost", "127.0.0.1")


@dataclass(frozen=True)
class Node:
    """One node's files: who it is, its key pair, its settings as written."""

    common_name: str
    pair: KeyPair
    settings: ZenohSettings
    toml: Path
    json5: Path


def to_toml(settings: ZenohSettings) -> str:
    """The ``[zenoh]`` table of ``settings`` as guidebelt.toml spells it (strings JSON-quoted,
    which TOML reads alike)."""
    q = json.dumps
    lines = [
        "[zenoh]",
        f"mode = {q(settings.mode)}",
        f"listen = {q(settings.listen)}",
        f"connect = {q(settings.connect)}",
        f"multicast_scouting = {q(settings.multicast_scouting)}",
    ]
    if settings.tls is not None:
        lines += [
            "",
            "[zenoh.tls]",
            f"root_ca = {q(settings.tls.root_ca)}",
            f"certificate = {q(settings.tls.certificate)}",
            f"private_key = {q(settings.tls.private_key)}",
        ]
    if settings.access is not None:
        lines += [
            "",
            "[zenoh.access]",
            f"users = {q(settings.access.users)}",
            f"services = {q([str(s) for s in settings.access.services])}",
        ]
    return "\n".join(lines) + "\n"


def certify(
    out: Path,
    users: list[str],
    services: list[Role],
    endpoint: str = DEFAULT_ENDPOINT,
    hosts: tuple[str, ...] = DEFAULT_HOSTS,
    installed_at: Path | None = None,
    new_ca: bool = False,
) -> list[Node]:
    """Certificates and configs for the daemon, each user's nodes and the services, in
    ``out``. The CA there is kept (nodes certified before stay valid) unless ``new_ca``.
    ``installed_at`` is where the files will be read from, if not ``out`` (a staging folder
    copied to /etc/guidebelt/tls later); ``hosts`` are the names nodes dial the daemon by."""
    out.mkdir(parents=True, exist_ok=True)
    try:
        ca = make_ca(out) if new_ca else load_ca(out)
    except FileNotFoundError:
        ca = make_ca(out)
    at = (installed_at or out).absolute()

    def tls(stem: str) -> TlsSettings:
        return TlsSettings(
            root_ca=str(at / ca.certificate.name),
            certificate=str(at / f"{stem}.pem"),
            private_key=str(at / f"{stem}.key"),
        )

    nodes: list[tuple[str, str, ZenohSettings, tuple[str, ...]]] = [
        (
            DAEMON_STEM,
            DAEMON_STEM,
            ZenohSettings(
                listen=[endpoint],
                tls=tls(DAEMON_STEM),
                access=AccessSettings(users=users, services=services),
            ),
            hosts,
        )
    ]
    for who in identities_for(users, services):
        nodes.append(_client(who, endpoint, tls(who.stem)))
    written = []
    for common_name, stem, settings, sans in nodes:
        pair = issue(ca, common_name, out, stem, hosts=sans)
        toml, json5 = out / f"{stem}.toml", out / f"{stem}.json5"
        toml.write_text(to_toml(settings))
        json5.write_text(settings.to_json5() + "\n")
        written.append(Node(common_name, pair, settings, toml, json5))
    return written


def _client(
    who: Identity, endpoint: str, tls: TlsSettings
) -> tuple[str, str, ZenohSettings, tuple[str, ...]]:
    # A node that only dials the daemon needs no host names in its certificate.
    return who.common_name, who.stem, ZenohSettings(connect=[endpoint], tls=tls), ()
