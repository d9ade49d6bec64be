"""``guidebelt view``: a live web page of every user's walk, read-only, on 127.0.0.1."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer

from .peer import Connect, Listen, Scout, ZenohConfig, open_peer


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
    demo: Annotated[
        int,
        typer.Option(
            help="N > 0: watch N simulated users walk the demo courtyard again and again "
            "through a daemon in this process (no other node needed)"
        ),
    ] = 0,
    connect: Connect = None,
    listen: Listen = None,
    scout: Scout = False,
    zenoh_config: ZenohConfig = None,
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
    if demo > 0:
        _serve_demo(demo, settings)
        return
    session = open_peer(connect, scout, zenoh_config, listen)
    state = ViewState()
    typer.echo(f"guidebelt view on {settings.url()}")
    try:
        with ViewNode(session, state):
            uvicorn.Server(uvicorn_config(state, settings)).run()
    finally:
        session.close()


def _serve_demo(users: int, settings) -> None:
    """Daemon, ``users`` walkers and the view, all here; until Ctrl-C."""
    import time

    from daemon.service.embedded import DaemonThread, free_port
    from daemon.service.logs import setup_logging
    from protocol.session import ZenohSettings, open_session
    from sim.courtyard import USER_RADIUS_M
    from sim.live import LiveWalks, endpoints
    from viewer.server import ViewThread

    setup_logging("WARNING")
    names = [f"demo{i}" for i in range(users)]
    with DaemonThread(backend="cpu", cell_m=0.1, user_radius_m=USER_RADIUS_M) as daemon:
        zport = free_port()
        session = open_session(
            ZenohSettings(listen=endpoints(zport), connect=endpoints(daemon.port))
        )
        try:
            with (
                ViewThread(session, settings),
                LiveWalks(daemon.port, names, observers=[zport], rounds=0, timeout_s=600),
            ):
                typer.echo(f"guidebelt view on {settings.url()} ({users} simulated users)")
                try:
                    while True:
                        time.sleep(1.0)
                except KeyboardInterrupt:
                    pass
        finally:
            session.close()


def register(app: typer.Typer) -> None:
    app.command("view")(view)
