"""``guidebelt view``: a live web page of every user's walk, read-only, on 127.0.0.1."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer

from .peer import Connect, Listen, Scout, open_peer


def view(
    host: Annotated[
        str, typer.Option(help="address to serve on; anything but loopback shows walks to others")
    ] = "127.0.0.1",
    port: Annotated[int, typer.Option(help="port of the page")] = 8765,
    hz: Annotated[float, typer.Option(help="frames a second pushed to each page (1..60)")] = 10.0,
    cert: Annotated[
        Path | None, typer.Option(help="TLS certificate (PEM): serve https/wss only")
    ] = None,
    key: Annotated[Path | None, typer.Option(help="the certificate's private key (PEM)")] = None,
    connect: Connect = None,
    listen: Listen = None,
    scout: Scout = False,
) -> None:
    """Serve a page with the map, path, pose, goal, belt motors, voice cues and status."""
    import uvicorn

    from viewer.node import ViewNode
    from viewer.server import ServeSettings, uvicorn_config
    from viewer.state import ViewState

    try:
        settings = ServeSettings(host=host, port=port, hz=hz, certfile=cert, keyfile=key)
    except ValueError as exc:
        raise typer.BadParameter(str(exc)) from exc
    session = open_peer(connect, scout, listen)
    state = ViewState()
    typer.echo(f"guidebelt view on {settings.url()}")
    try:
        with ViewNode(session, state):
            uvicorn.Server(uvicorn_config(state, settings)).run()
    finally:
        session.close()


def register(app: typer.Typer) -> None:
    app.command("view")(view)
