"""Options shared by the commands that talk to a running daemon as a zenoh peer."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer

Connect = Annotated[
    list[str] | None,
    typer.Option("--connect", help="zenoh endpoint of the daemon (repeatable)"),
]
Scout = Annotated[
    bool, typer.Option("--scout/--no-scout", help="find the daemon by multicast scouting")
]
ZenohConfig = Annotated[
    Path | None,
    typer.Option(
        "--zenoh-config",
        help="this node's [zenoh] table, as `guidebelt certs` writes it (TLS certificate, "
        "endpoints); --connect/--listen given too replace its endpoints",
    ),
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


def node_settings(
    zenoh_config: Path | None,
    connect: list[str] | None = None,
    listen: list[str] | None = None,
    scout: bool = False,
):  # -> ZenohSettings, imported lazily
    """The node's zenoh settings: from ``--zenoh-config`` when given (a missing certificate
    or a bad table is one line and exit 2, as for ``guidebelt run``), else from the options."""
    from pydantic import ValidationError

    from protocol.settings import ZenohSettings, load_node_settings

    if zenoh_config is None:
        if not (connect or listen or scout):
            connect = [DEFAULT_ENDPOINT]  # no way named to meet the daemon: its default one
        return ZenohSettings(connect=connect or [], listen=listen or [], multicast_scouting=scout)
    try:
        settings = load_node_settings(zenoh_config)
        changes = {k: v for k, v in (("connect", connect), ("listen", listen)) if v}
        if changes:
            settings = ZenohSettings.model_validate({**settings.model_dump(), **changes})
        problems = settings.problems()
    except ValidationError as exc:
        problems = [f"{'.'.join(map(str, e['loc']))}: {e['msg']}" for e in exc.errors()]
    except OSError as exc:
        problems = [str(exc)]
    if problems:
        typer.echo(f"bad zenoh config {zenoh_config}: {'; '.join(problems)}", err=True)
        raise typer.Exit(2)
    return settings


def open_peer(
    connect: list[str] | None,
    scout: bool,
    zenoh_config: Path | None = None,
    listen: list[str] | None = None,
):  # -> zenoh.Session, imported lazily
    """A session with the daemon; ``listen`` adds endpoints others may dial (a view or a
    recorder that no router relays for)."""
    from protocol.session import open_session

    return open_session(node_settings(zenoh_config, connect, listen, scout))
