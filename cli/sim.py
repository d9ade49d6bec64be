"""``guidebelt sim``: the simulated world as a zenoh node, next to a running daemon."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer

from .peer import Connect, Scout, ZenohConfig, open_peer


def sim(
    user: Annotated[str, typer.Option(help="the simulated user's name")] = "sim",
    grid: Annotated[int, typer.Option(help="courtyard side in cells (100 = 10 cm cells)")] = 100,
    unknown: Annotated[float, typer.Option(help="unknown obstacles, fraction of free area")] = 0.4,
    seed: Annotated[int, typer.Option(help="scenario seed")] = 0,
    follow: Annotated[str, typer.Option(help="walker: what the user follows (path…)")] = "path",
    send_goal: Annotated[
        bool, typer.Option("--send-goal/--no-send-goal", help="send the courtyard's goal too")
    ] = True,
    step_period: Annotated[float, typer.Option(help="seconds between steps (0: lock step)")] = 0.0,
    timeout: Annotated[float, typer.Option(help="give up after this many seconds")] = 300.0,
    out: Annotated[Path | None, typer.Option(help="save a picture of the walk here")] = None,
    connect: Connect = None,
    scout: Scout = False,
    zenoh_config: ZenohConfig = None,
) -> None:
    """Play the world for one user: sensor deltas, poses, a walker; exit 0 once arrived."""
    import signal
    import threading
    import time

    from protocol.messages import Goal, GoalCell
    from sim.courtyard import make_courtyard
    from sim.node import SimNode, SimResult
    from sim.world import WALKERS

    if follow not in WALKERS:
        raise typer.BadParameter(f"choose one of {sorted(WALKERS)}", param_hint="--follow")
    scenario = make_courtyard(grid, unknown, seed)
    session = open_peer(connect, scout, zenoh_config)
    stop = threading.Event()
    signal.signal(signal.SIGTERM, lambda *_: stop.set())
    goal = None
    if send_goal:  # sent when the daemon's token appears, and again after a restart
        row, col = scenario.goal
        goal = Goal(target=GoalCell(row=row, col=col), stamp=time.time())
    node = SimNode(session, user, scenario, walker=follow, step_period_s=step_period, goal=goal)

    def progress(r: SimResult) -> None:
        if r.steps % 10 == 0:
            typer.echo(f"step {r.steps}: at {r.walked[-1]}", err=True)

    try:
        result = node.run(stop, timeout_s=timeout, on_step=progress)
    except KeyboardInterrupt:
        stop.set()
        raise typer.Exit(130) from None
    finally:
        session.close()
    ms = sorted(result.step_ms)
    typer.echo(
        f"{result.reason}: {result.steps} steps, "
        f"{ms[len(ms) // 2] if ms else float('nan'):.1f} ms per step (median, pose → path)"
    )
    if out is not None:
        from cli.demo_world import render_sim

        render_sim(scenario, result, out)
        typer.echo(f"picture: {out}")
    raise typer.Exit(0 if result.arrived else 1)


def register(app: typer.Typer) -> None:
    app.command("sim")(sim)
