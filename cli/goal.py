"""``guidebelt goal USER X Y``: send a goal, then follow the user's status for a while."""

from __future__ import annotations

import time
from typing import Annotated

import typer

from .peer import Connect, Scout, ZenohConfig, open_peer


def goal(
    user: Annotated[str, typer.Argument(help="user name, [a-z0-9_-]")],
    x: Annotated[float, typer.Argument(help="metres east (or the row with --cell)")],
    y: Annotated[float, typer.Argument(help="metres north (or the column with --cell)")],
    cell: Annotated[bool, typer.Option("--cell", help="X Y are a grid row and column")] = False,
    wait: Annotated[float, typer.Option(help="seconds to print status updates")] = 2.0,
    connect: Connect = None,
    scout: Scout = False,
    zenoh_config: ZenohConfig = None,
) -> None:
    """Send USER a goal at (X, Y)."""
    from zenoh.handlers import Callback

    from protocol import codec
    from protocol import session as wire
    from protocol import topics as T
    from protocol.messages import Goal, GoalCell, GoalMetres, NavStatus

    T.check_user(user)
    target = GoalCell(row=int(x), col=int(y)) if cell else GoalMetres(x=x, y=y)
    session = open_peer(connect, scout, zenoh_config)
    final: list[NavStatus] = []

    def on_status(sample) -> None:
        status = codec.decode(NavStatus, sample.payload.to_bytes())
        final.append(status)
        typer.echo(f"{status.state.value:>9} {status.code or '-':<16} {status.reason}")

    sub = wire.declare_subscriber(session, T.STATUS, Callback(on_status), user)
    try:
        time.sleep(0.1)
        goal_msg = Goal(target=target, stamp=time.time())
        wire.put(session, T.GOAL, user, codec.encode(goal_msg))
        typer.echo(f"goal sent to {user}: {target.model_dump_json()}")
        time.sleep(wait)
    finally:
        sub.undeclare()
        session.close()
    if final and final[-1].state.value in ("no_path", "error"):
        raise typer.Exit(1)


def register(app: typer.Typer) -> None:
    app.command("goal")(goal)
