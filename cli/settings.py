"""``guidebelt settings USER [--intensity N] [--voice V] [--wording W] [--units U]``: show a
user's settings, or change some (the others stay as they are).

A change goes on the user's own ``settings/set`` key, and the command waits for the daemon
to publish the settings it applied (and stored) on ``settings``: a change the daemon did not
take fails the command.
"""

from __future__ import annotations

import threading
import time
from typing import Annotated

import typer

from .peer import Connect, Scout, ZenohConfig, open_peer


def settings(
    user: Annotated[str, typer.Argument(help="user name, [a-z0-9_-]")],
    intensity: Annotated[
        int | None, typer.Option(min=0, max=100, help="belt intensity, 0 (40 % floor) to 100")
    ] = None,
    voice: Annotated[
        str | None, typer.Option(help="companion (beside the belt) or sole (voice alone)")
    ] = None,
    wording: Annotated[str | None, typer.Option(help="clock or sides")] = None,
    units: Annotated[str | None, typer.Option(help="metric or imperial")] = None,
    timeout: Annotated[float, typer.Option(help="seconds to wait for the daemon")] = 3.0,
    connect: Connect = None,
    scout: Scout = False,
    zenoh_config: ZenohConfig = None,
) -> None:
    """Show USER's settings, or change them (--intensity, --voice, --wording, --units)."""
    from pydantic import ValidationError
    from zenoh.handlers import Callback

    from protocol import codec
    from protocol import session as wire
    from protocol import topics as T
    from protocol.messages import UserSettings

    T.check_user(user)
    asked = {"intensity": intensity, "voice": voice, "wording": wording, "units": units}
    asked = {k: v for k, v in asked.items() if v is not None}
    try:
        change = UserSettings(**asked, stamp=time.time()) if asked else None
    except ValidationError as exc:  # a bad value, said in one line
        first = exc.errors()[0]
        where = ".".join(str(p) for p in first["loc"])
        raise typer.BadParameter(f"--{where}: {first['msg']}") from exc
    session = open_peer(connect, scout, zenoh_config)
    got: list[UserSettings] = []
    done = threading.Event()

    def on_settings(payload: bytes) -> None:
        msg = codec.decode(UserSettings, payload)
        if all(getattr(msg, k) == v for k, v in asked.items()):
            got.append(msg)
            done.set()

    try:
        if change is None:
            for reply in wire.get(session, T.SETTINGS_QUERY, user, timeout=timeout):
                if reply.ok is not None:
                    on_settings(reply.ok.payload.to_bytes())
        else:
            sub = wire.declare_subscriber(
                session, T.SETTINGS, Callback(lambda s: on_settings(s.payload.to_bytes())), user
            )
            try:
                time.sleep(0.1)  # the subscription reaches the daemon before the change
                wire.put(session, T.SETTINGS_SET, user, codec.encode(change))
                done.wait(timeout)
            finally:
                sub.undeclare()
    finally:
        session.close()
    if not got:
        typer.echo(f"no settings for {user!r} from a daemon within {timeout:g} s", err=True)
        raise typer.Exit(1)
    typer.echo(f"{user}: {got[-1].model_dump_json()}")


def register(app: typer.Typer) -> None:
    app.command("settings")(settings)
