"""``guidebelt status USER``: the user's latest navigation status and the daemon's health."""

from __future__ import annotations

from typing import Annotated

import typer

from .peer import Connect, Scout, ZenohConfig, open_peer


def status(
    user: Annotated[str, typer.Argument(help="user name, or '*' for every user")],
    timeout: Annotated[float, typer.Option(help="seconds to wait for answers")] = 2.0,
    connect: Connect = None,
    scout: Scout = False,
    zenoh_config: ZenohConfig = None,
) -> None:
    """Ask the daemon for USER's status; exit 1 when nobody answers."""
    from protocol import codec
    from protocol import session as wire
    from protocol import topics as T
    from protocol.messages import Health, NavStatus

    if user != "*":
        T.check_user(user)
    session = open_peer(connect, scout, zenoh_config)
    try:
        answered = False
        for reply in wire.get(session, T.STATUS_QUERY, user, timeout=timeout):
            if reply.ok is not None:
                answered = True
                st = codec.decode(NavStatus, reply.ok.payload.to_bytes())
                typer.echo(f"{T.user_of(reply.ok.key_expr)}: {st.model_dump_json()}")
        for reply in wire.get(session, T.HEALTH, timeout=timeout):
            if reply.ok is not None:
                health = codec.decode(Health, reply.ok.payload.to_bytes())
                typer.echo(f"daemon: {health.model_dump_json()}")
    finally:
        session.close()
    if not answered:
        typer.echo(f"no status for {user!r}", err=True)
        raise typer.Exit(1)


def register(app: typer.Typer) -> None:
    app.command("status")(status)
