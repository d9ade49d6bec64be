"""``guidebelt belt``: the haptic belt driver (zenoh belt patterns → serial frames → Nano)."""

from __future__ import annotations

from typing import Annotated

import typer

from .peer import ZenohConfig, node_settings


def belt(
    port: Annotated[
        str,
        typer.Option(help="Serial port of the Nano (/dev/ttyUSB0) or the simulator's pty link."),
    ],
    user: Annotated[str, typer.Option(help="User whose belt patterns to follow.")] = "default",
    connect: Annotated[
        list[str] | None, typer.Option(help="Zenoh endpoint to connect to (repeatable).")
    ] = None,
    listen: Annotated[
        list[str] | None, typer.Option(help="Zenoh endpoint to listen on (repeatable).")
    ] = None,
    multicast: Annotated[
        bool, typer.Option("--multicast/--no-multicast", help="Zenoh multicast scouting.")
    ] = False,
    log_level: Annotated[str, typer.Option(help="DEBUG, INFO, WARNING or ERROR.")] = "INFO",
    zenoh_config: ZenohConfig = None,
) -> None:
    """Drive the belt: follow the user's patterns, publish link health, STOP if the daemon dies."""
    import asyncio
    import logging
    import signal

    from drivers.belt.service import serve
    from protocol.topics import check_user

    logging.basicConfig(level=log_level.upper(), format="%(levelname)s %(name)s: %(message)s")
    try:
        check_user(user)
    except ValueError as exc:
        raise typer.BadParameter(str(exc)) from exc
    settings = node_settings(zenoh_config, connect, listen, multicast)

    async def main() -> None:
        stop = asyncio.Event()
        loop = asyncio.get_running_loop()
        for sig in (signal.SIGINT, signal.SIGTERM):
            loop.add_signal_handler(sig, stop.set)
        await serve(port, user, settings, stop)

    try:
        import uvloop
    except ImportError:
        asyncio.run(main())
    else:
        uvloop.run(main())


def register(app: typer.Typer) -> None:
    app.command("belt")(belt)
