"""Options shared by the commands that talk to a running daemon as a zenoh peer."""

from __future__ import annotations

from typing import Annotated

import typer

Connect = Annotated[
    list[str] | None,
    typer.Option("--connect", help="zenoh endpoint of the daemon (repeatable)"),
]
Scout = Annotated[
    bool, typer.Option("--scout/--no-scout", help="find the daemon by multicast scouting")
]
Listen = Annotated[
    list[str] | None,
    typer.Option(
        "--listen",
        help="zenoh endpoint to listen on as well, for nodes that reach no router "
        "(repeatable, e.g. tcp/127.0.0.1:7448)",
    ),
]
DEFAULT_ENDPOINT = "tcp/127.0.0.1:7447"


def open_peer(
    connect: list[str] | None, scout: bool, listen: list[str] | None = None
):  # -> zenoh.Session, imported lazily
    from protocol.session import ZenohSettings, open_session

    endpoints = connect if connect else ([] if scout or listen else [DEFAULT_ENDPOINT])
    settings = ZenohSettings(connect=endpoints, listen=listen or [], multicast_scouting=scout)
    return open_session(settings)
