"""``guidebelt load``: many users at once against a real daemon process (its own), the
delta→belt latency the served users feel, and who was told ``overloaded``."""

from __future__ import annotations

from typing import Annotated

import typer


def load(
    users: Annotated[int, typer.Option(min=1, max=2000, help="wearers played at once")] = 50,
    grid: Annotated[int, typer.Option(min=20, max=2000, help="each user's map side, cells")] = 200,
    pose_hz: Annotated[float, typer.Option(min=0.5, max=100)] = 20.0,
    delta_hz: Annotated[float, typer.Option(min=0.5, max=100)] = 10.0,
    seconds: Annotated[float, typer.Option(min=2, max=3600, help="seconds measured")] = 30.0,
    warmup: Annotated[
        float, typer.Option(min=0, max=600, help="seconds not measured, once all have joined")
    ] = 5.0,
    backend: Annotated[str, typer.Option(help="the daemon's backend")] = "cpu",
    workers: Annotated[
        int | None,
        typer.Option(min=0, max=64, help="the daemon's worker processes (default: its config's)"),
    ] = None,
    tls: Annotated[
        bool, typer.Option(help="mutual TLS and access rules, as shipped (certificates made here)")
    ] = False,
    json_out: Annotated[str, typer.Option("--json", help="also write the result here")] = "",
) -> None:
    """Start `guidebelt run` on a free loopback port and play USERS wearers against it:
    poses at POSE_HZ, map deltas at DELTA_HZ (each one changes the path). Prints the
    delta→belt latency over the users it served, how many it shed as `overloaded`, and
    every `stale_pose` (all false: the poses are always fresh)."""
    import json
    from pathlib import Path

    from sim.load import LoadSpec, run_against_daemon

    spec = LoadSpec(users, grid, pose_hz, delta_hz, seconds, warmup)
    env = {} if workers is None else {"GUIDEBELT_WORKERS": str(workers)}
    result = run_against_daemon(spec, backend, env, tls=tls)
    text = json.dumps(result, indent=2)
    typer.echo(text)
    if json_out:
        Path(json_out).write_text(text + "\n")


def register(app: typer.Typer) -> None:
    app.command("load")(load)
