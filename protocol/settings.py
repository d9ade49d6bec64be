"""Where a node meets the others: zenoh settings shared by every guidebelt process.

Kept apart from ``protocol.session`` (which opens the session) so that a configuration can
be read and validated where zenoh is not installed, e.g. the GPU benchmark machine.
"""

from __future__ import annotations

import ipaddress
import json
import os
from pathlib import Path
from typing import Annotated, Any, Literal

from pydantic import BaseModel, ConfigDict, Field, model_validator

from .access import SERVICE_ROLES, access_control, identities_for
from .topics import USER_RE, Role

Endpoint = Annotated[str, Field(min_length=3, max_length=200, pattern=r"^[a-z0-9-]+/\S+$")]
"""A zenoh locator, ``proto/address``: tcp/127.0.0.1:7447, tls/host:7447, …"""
PemPath = Annotated[str, Field(min_length=1, max_length=1024, description="a PEM file")]
User = Annotated[str, Field(pattern=USER_RE.pattern)]
Service = Literal[Role.MAPPER, Role.SIM, Role.MONITOR]
LOOPBACK_NAMES = ("localhost",)


class TlsSettings(BaseModel):
    """This node's certificate, its key, and the CA that signed every node's (mutual TLS)."""

    model_config = ConfigDict(extra="forbid")

    root_ca: PemPath
    certificate: PemPath
    private_key: PemPath

    def problems(self) -> list[str]:
        """Files that are missing or unreadable, one phrase each (checked at start)."""
        out = []
        for name in ("root_ca", "certificate", "private_key"):
            path = Path(getattr(self, name))
            if not path.is_file():
                out.append(f"zenoh.tls.{name}: {path} not found")
            elif not os.access(path, os.R_OK):
                out.append(f"zenoh.tls.{name}: {path} not readable")
        return out


class AccessSettings(BaseModel):
    """Who may connect to this node and what each may do (``protocol.access``): set on the
    daemon, the node every other one connects to."""

    model_config = ConfigDict(extra="forbid")

    users: list[User] = Field(
        default_factory=list, max_length=1000,
        description="each gets user:, belt:, voice: and rfid: identities for their own keys",
    )  # fmt: skip
    services: list[Service] = Field(
        default_factory=lambda: [Role.MAPPER, Role.MONITOR], max_length=len(SERVICE_ROLES),
        description="mapper, sim, monitor: every user's keys, as the topic table grants",
    )  # fmt: skip

    def config(self) -> dict[str, Any]:
        return access_control(identities_for(self.users, self.services))


class ZenohSettings(BaseModel):
    """Where a node meets the others: the ``[zenoh]`` table of every guidebelt process."""

    model_config = ConfigDict(extra="forbid")

    mode: Literal["peer", "client"] = "peer"
    listen: list[Endpoint] = Field(
        default_factory=list, max_length=16, description="e.g. tcp/127.0.0.1:7447"
    )
    connect: list[Endpoint] = Field(
        default_factory=list, max_length=16, description="routers or peers to join"
    )
    multicast_scouting: bool = Field(
        default=False,
        description="find peers on the LAN without naming them: off unless asked for",
    )
    tls: TlsSettings | None = Field(
        default=None, description="mutual TLS: every endpoint tls/, every peer certified"
    )
    access: AccessSettings | None = Field(
        default=None, description="access control by certificate name (the daemon's side)"
    )

    @model_validator(mode="after")
    def _coherent(self) -> ZenohSettings:
        if self.tls is not None:
            plain = [e for e in self.listen + self.connect if not e.startswith("tls/")]
            if plain:
                raise ValueError(f"with [zenoh.tls] every endpoint must be tls/: {plain}")
            if self.multicast_scouting:
                raise ValueError("with [zenoh.tls] multicast scouting stays off")
        if self.access is not None and self.tls is None:
            raise ValueError("[zenoh.access] names certificates: it needs [zenoh.tls]")
        return self

    def problems(self) -> list[str]:
        """What would stop this node at start (TLS files missing or unreadable)."""
        return self.tls.problems() if self.tls is not None else []

    def loopback_only(self) -> bool:
        """Whether every endpoint is on this host (127.0.0.0/8, ::1, localhost)."""
        return not self.multicast_scouting and all(
            _is_loopback(e) for e in self.listen + self.connect
        )

    def to_json5(self) -> str:
        config: dict[str, Any] = {
            "mode": self.mode,
            "listen": {"endpoints": self.listen},
            "connect": {"endpoints": self.connect},
            "scouting": {
                "multicast": {"enabled": self.multicast_scouting},
                # Gossip would reach peers the config did not name: off whenever
                # multicast is, so a test's sessions on loopback meet no one else's.
                "gossip": {"enabled": self.multicast_scouting},
            },
        }
        if self.tls is not None:
            cert, key = self.tls.certificate, self.tls.private_key
            config["transport"] = {
                "link": {
                    # Only TLS links, accepted or opened: a plain tcp/ peer is refused even
                    # where an endpoint was added by hand.
                    "protocols": ["tls"],
                    "tls": {
                        "root_ca_certificate": self.tls.root_ca,
                        "enable_mtls": True,
                        "listen_certificate": cert,
                        "listen_private_key": key,
                        "connect_certificate": cert,
                        "connect_private_key": key,
                        "verify_name_on_connect": True,
                    },
                },
                # Large payloads would otherwise travel through shared-memory segments
                # beside the TLS link, outside what the certificates protect.
                "shared_memory": {"enabled": False},
            }
        if self.access is not None:
            config["access_control"] = self.access.config()
        return json.dumps(config)


def _is_loopback(endpoint: str) -> bool:
    address = endpoint.split("/", 1)[1].split("#", 1)[0].split("?", 1)[0]
    host = address.rsplit(":", 1)[0].strip("[]")
    if host in LOOPBACK_NAMES:
        return True
    try:
        return ipaddress.ip_address(host).is_loopback
    except ValueError:
        return False


def loopback(listen_port: int | None = None, connect_port: int | None = None) -> ZenohSettings:
    """Settings for tests and the demo: 127.0.0.1 only, no scouting."""
    return ZenohSettings(
        listen=[f"tcp/127.0.0.1:{listen_port}"] if listen_port else [],
        connect=[f"tcp/127.0.0.1:{connect_port}"] if connect_port else [],
        multicast_scouting=False,
    )


def load_node_settings(path: str | Path) -> ZenohSettings:
    """A node's ``[zenoh]`` table from the TOML file ``guidebelt certs`` wrote for it, with
    ``GUIDEBELT_ZENOH__…`` environment variables over it as for the daemon: a unit passes its
    private key from systemd's credentials this way (``%d``), the file need not know where."""
    from pydantic_settings import (
        BaseSettings,
        PydanticBaseSettingsSource,
        SettingsConfigDict,
        TomlConfigSettingsSource,
    )

    if not Path(path).is_file():
        raise FileNotFoundError(f"zenoh config {path} not found")

    class NodeConfig(BaseSettings):
        model_config = SettingsConfigDict(
            env_prefix="GUIDEBELT_", env_nested_delimiter="__", extra="ignore", toml_file=path
        )
        zenoh: ZenohSettings

        @classmethod
        def settings_customise_sources(
            cls,
            settings_cls: type[BaseSettings],
            init_settings: PydanticBaseSettingsSource,
            env_settings: PydanticBaseSettingsSource,
            **_: PydanticBaseSettingsSource,
        ) -> tuple[PydanticBaseSettingsSource, ...]:
            return (init_settings, env_settings, TomlConfigSettingsSource(settings_cls))

    return NodeConfig().zenoh
