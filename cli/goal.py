"""``guidebelt goal USER X Y``: send a goal, then follow the user's status for a while."""

from __future__ import annotations

import time
from typing import Annotated

import typer

from .peer import Connect, Scout, open_peer


def goal(
    user: Annotated[str, typer.Argument(help="user name, [a-z0-9_-]")],
    x: Annotated[float, typer.Argument(help="metres east (or the row with --cell)")],
    y: Annotated[float, typer.Argument(help="metres north (or the column with --cell)")],
    cell: Annotated[bool, typer.Option("--cell", help="X Y are a grid row and column")] = False,
    wait: Annotated[float, typer.Option(help="seconds to print status updates")] = 2.0,
    connect: Connect = None,
    scout: Scout = False,
) -> None:
    """Send USER a goal at (X, Y)."""
    from zenoh import CongestionControl
    from zenoh.handlers import Callback

    from protocol import codec, keys
    from protocol.messages import Goal, GoalCell, GoalMetres, NavStatus

    BLOCK = CongestionControl.BLOCK  # a goal must not be dropped on a busy link

    keys.check_user(user)
    target = GoalCell(row=int(x), col=int(y)) if cell else GoalMetres(x=x, y=y)
    session = open_peer(connect, scout)
    final: list[NavStatus] = []

    def on_status(sample) -> None:
        status = codec.decode(NavStatus, sample.payload.to_bytes())
        final.append(status)
        typer.echo(f"{status.state.value:>9} {status.code or '-':<16} {status.reason}")

    sub = session.declare_subscriber(keys.status(user), Callback(on_status))
    try:
        time.sleep(0.1)
        goal_msg = Goal(target=target, stamp=time.time())
        session.put(keys.goal(user), codec.encode(goal_msg), congestion_control=BLOCK)
        typer.echo(f"goal sent to {user}: {target.model_dump_json()}")
        time.sleep(wait)
    finally:
        sub.undeclare()
        session.close()
    if final and final[-1].state.value in ("no_path", "error"):
        raise typer.Exit(1)


def register(app: typer.Typer) -> None:
    app.command("goal")(goal)
