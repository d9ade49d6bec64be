"""``guidebelt replay``: a recording back over zenoh, or checked against a fresh daemon."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer

from .peer import Connect, Scout, ZenohConfig, open_peer


def replay(
    recording: Annotated[Path, typer.Argument(help="MCAP file written by guidebelt record")],
    speed: Annotated[float, typer.Option(help="times real time (0: as fast as possible)")] = 1.0,
    what: Annotated[
        str, typer.Option(help="inputs (to drive a daemon), outputs (to drive a view) or all")
    ] = "all",
    check: Annotated[
        bool,
        typer.Option(
            "--check",
            help="run a fresh daemon on the recorded inputs and report where its belt "
            "patterns and statuses differ from the recorded ones (exit 1 if any do)",
        ),
    ] = False,
    connect: Connect = None,
    scout: Scout = False,
    zenoh_config: ZenohConfig = None,
) -> None:
    """Publish RECORDING's messages, re-stamped to now, on their keys."""
    from rich.console import Console

    from recording.replay import Player, read, select

    if not recording.is_file():
        raise typer.BadParameter(f"{recording}: no such file")
    console = Console()
    try:
        items = list(read(recording))
    except Exception as exc:  # a bad file is one line, whatever the reader raised
        typer.echo(f"guidebelt replay: {recording}: {type(exc).__name__}: {exc}", err=True)
        raise typer.Exit(2) from None
    if check:
        _check(recording, items, console)
        return
    try:
        chosen = select(items, what)
    except ValueError as exc:
        raise typer.BadParameter(str(exc)) from exc
    session = open_peer(connect, scout, zenoh_config)
    player = Player(session, chosen, speed)
    try:
        with _bar(console) as bar:
            task = bar.add_task(f"replaying {recording.name}", total=len(chosen))
            player.run(on_sent=lambda n: bar.update(task, completed=n))
    finally:
        player.close()
        session.close()
    console.print(f"{player.sent} of {len(chosen)} messages published")


def _bar(console):
    from rich.progress import (
        BarColumn,
        MofNCompleteColumn,
        Progress,
        TextColumn,
        TimeElapsedColumn,
        TimeRemainingColumn,
    )

    return Progress(TextColumn("{task.description}"), BarColumn(), MofNCompleteColumn(),
                    TimeElapsedColumn(), TimeRemainingColumn(), console=console)  # fmt: skip


def _check(recording: Path, items, console) -> None:
    from daemon.service.embedded import DaemonThread
    from daemon.service.logs import setup_logging
    from recording.check import check, split
    from recording.replay import metadata

    setup_logging("WARNING")
    meta = metadata(recording)
    config = {k: meta[k] for k in ("planner", "backend", "cell_m", "user_radius_m") if k in meta}
    inputs, _, _ = split(items)
    with DaemonThread(**config) as daemon:
        session = daemon.peer()
        try:
            with _bar(console) as bar:
                task = bar.add_task("fresh daemon on the recorded inputs", total=len(inputs))
                report = check(session, items, lambda n: bar.update(task, completed=n))
        finally:
            session.close()
    console.print(
        f"{report.inputs} inputs fed in order ({report.unanswered} without an answer, as some "
        f"were in the recording); compared the belt patterns of {report.steps_compared} "
        f"planning steps and {report.statuses_compared} statuses (repeats folded)",
        soft_wrap=True,
    )
    for diff in report.differences:
        console.print(f"differs: {diff}", soft_wrap=True)
    if report.differences:
        raise typer.Exit(1)
    console.print("no difference")


def register(app: typer.Typer) -> None:
    app.command("replay")(replay)
