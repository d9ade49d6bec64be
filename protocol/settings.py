"""Where a node meets the others: zenoh settings shared by every guidebelt process.

Kept apart from ``protocol.session`` (which opens the session) so that a configuration can
be read and validated where zenoh is not installed, e.g. the GPU benchmark machine.
"""

from __future__ import annotations

import json
from typing import Annotated, Literal

from pydantic import BaseModel, ConfigDict, Field

Endpoint = Annotated[str, Field(min_length=3, max_length=200, pattern=r"^[a-z0-9-]+/\S+$")]
"""A zenoh locator, ``proto/address``: tcp/127.0.0.1:7447, tls/host:7447, …"""


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

    def to_json5(self) -> str:
        return json.dumps(
            {
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
        )


def loopback(listen_port: int | None = None, connect_port: int | None = None) -> ZenohSettings:
    """Settings for tests and the demo: 127.0.0.1 only, no scouting."""
    return ZenohSettings(
        listen=[f"tcp/127.0.0.1:{listen_port}"] if listen_port else [],
        connect=[f"tcp/127.0.0.1:{connect_port}"] if connect_port else [],
        multicast_scouting=False,
    )
