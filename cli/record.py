"""``guidebelt record``: every message of a user's session into an MCAP file."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer

from .peer import Connect, Listen, Scout, ZenohConfig, open_peer


def record(
    out: Annotated[Path, typer.Option(help="MCAP file (rotated as walk.001.mcap, …)")] = Path(
        "walk.mcap"
    ),
    user: Annotated[str, typer.Option(help="user to record, or '*' for every user")] = "*",
    max_mb: Annotated[float, typer.Option(help="rotate past this many MiB per file")] = 256.0,
    seconds: Annotated[float, typer.Option(help="stop after this long (0: until Ctrl-C)")] = 0.0,
    demo: Annotated[
        bool,
        typer.Option(help="record the demo walk: daemon and simulated user in this process"),
    ] = False,
    pace: Annotated[float, typer.Option(help="with --demo: seconds per step")] = 0.1,
    connect: Connect = None,
    listen: Listen = None,
    scout: Scout = False,
    zenoh_config: ZenohConfig = None,
) -> None:
    """Record USER's messages (inputs and the daemon's outputs) with their JSON Schemas."""
    from rich.console import Console

    from recording.recorder import Recorder

    console = Console()
    if demo:
        counts = record_demo(out, user if user != "*" else "demo", pace, max_mb, console)
    else:
        session = open_peer(connect, scout, zenoh_config, listen)
        try:
            with Recorder(session, out, user, int(max_mb * 2**20)) as rec:
                _progress(console, rec, lambda: False, seconds)
            counts = rec.counts
        finally:
            session.close()
    console.print(
        f"{counts.written} messages written to {counts.files} file(s) from {out}; "
        f"{counts.dropped} dropped, {counts.invalid} invalid, of {counts.heard} heard"
    )
    if counts.dropped:
        raise typer.Exit(1)


def _progress(console, rec, finished, seconds: float) -> None:
    """A live line of what is recorded, until ``finished()``, ``seconds`` or Ctrl-C."""
    import time

    from rich.progress import Progress, SpinnerColumn, TextColumn, TimeElapsedColumn

    end = time.monotonic() + seconds if seconds else None
    with Progress(SpinnerColumn(), TextColumn("{task.description}"), TimeElapsedColumn(),
                  console=console) as bar:  # fmt: skip
        task = bar.add_task("recording")
        try:
            while not finished() and (end is None or time.monotonic() < end):
                c = rec.counts
                bar.update(task, description=f"recording: {c.written} written, "
                           f"{rec.backlog()} queued, {c.dropped} dropped")  # fmt: skip
                time.sleep(0.2)
        except KeyboardInterrupt:
            pass


def record_demo(out: Path, user: str, pace: float, max_mb: float, console):
    """The demo walk (``guidebelt demo``'s courtyard) with a recorder beside the daemon."""
    import time

    from daemon.service.embedded import DaemonThread, free_port
    from daemon.service.logs import setup_logging
    from protocol.session import ZenohSettings, open_session
    from recording.recorder import Recorder
    from sim.courtyard import USER_RADIUS_M
    from sim.live import LiveWalks, endpoints

    setup_logging("WARNING")
    meta = {"planner": "eds", "backend": "cpu", "cell_m": 0.1, "user_radius_m": USER_RADIUS_M}
    with DaemonThread(planner="eds", backend="cpu", cell_m=0.1, user_radius_m=USER_RADIUS_M) as d:
        port = free_port()
        session = open_session(ZenohSettings(listen=endpoints(port), connect=endpoints(d.port)))
        try:
            with (
                Recorder(session, out, user, int(max_mb * 2**20), metadata=meta) as rec,
                LiveWalks(d.port, [user], observers=[port], pace_s=pace) as walks,
            ):
                _progress(console, rec, lambda: walks.join(0), 0)
                walks.join()
                time.sleep(0.3)  # the last step's outputs reach the recorder
        finally:
            session.close()
    return rec.counts


def register(app: typer.Typer) -> None:
    app.command("record")(record)
