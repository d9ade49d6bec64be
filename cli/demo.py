"""``guidebelt demo``: one simulated walk through the paper's courtyard.

For now the walk runs in this process (``--in-process``, the default): the simulated
sensor reveals obstacles, the planner repairs its field, the user steps along the path.
The daemon's issue adds the same walk over zenoh; ``run_in_process`` stays available.
"""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer

from cli.options import PLANNER_NAMES


def run_in_process(
    grid: int, unknown: float, seed: int, backend: str, mode: str, out: Path
) -> bool:
    """Walk once, print progress and a summary, save the picture; True when the user arrived."""
    import numpy as np
    from rich.console import Console

    from sim.courtyard import make_courtyard
    from sim.render import render_walk
    from sim.walk import walk

    console = Console()
    scenario = make_courtyard(grid=grid, unknown=unknown, seed=seed)
    console.print(
        f"courtyard {grid}x{grid} ({scenario.cell_m * 100:g} cm cells), "
        f"{unknown:.0%} unknown obstacles, seed {seed}, backend {backend}, {mode.upper()}"
    )
    with console.status("walking") as status:

        def progress(step: int, cell: tuple[int, int], changed: int, ms: float) -> None:
            status.update(f"step {step}: at {cell}, {changed} cells changed, {ms:.2f} ms")

        result = walk(scenario, backend=backend, mode=mode, on_step=progress)
    replans = int(np.count_nonzero(result.changed > 0))
    status = "arrived" if result.arrived else f"did not arrive ({result.reason})"
    console.print(f"{status}: {result.steps} steps, {result.walked_m:.1f} m walked", soft_wrap=True)
    console.print(
        f"{replans} steps changed the map; planning {np.median(result.step_ms):.2f} ms per step "
        f"(median), inflation {np.median(result.inflate_ms):.2f} ms",
        soft_wrap=True,
    )
    out.parent.mkdir(parents=True, exist_ok=True)
    render_walk(scenario, result, out)
    console.print(f"picture: {out}", soft_wrap=True)
    return result.arrived


def demo(
    in_process: Annotated[
        bool,
        typer.Option(
            "--in-process/--daemon",
            help="Walk in this process, or (default) through the daemon over zenoh.",
        ),
    ] = False,
    follow: Annotated[
        str,
        typer.Option(help="With the daemon: the walker feels the belt (belt) or reads the path."),
    ] = "belt",
    pace: Annotated[
        float,
        typer.Option(help="With the daemon: seconds per step (0.1 = 1 m/s at 10 cm; 0 = no wait)."),
    ] = 0.1,
    grid: Annotated[int, typer.Option(help="Grid side (100 = 10 cm cells).")] = 100,
    unknown: Annotated[
        float | None,
        typer.Option(help="Fraction of free area unknown (0.4; with --sensor camera 0.2)."),
    ] = None,
    seed: Annotated[int, typer.Option(help="Scenario seed.")] = 0,
    backend: Annotated[str, typer.Option(help="cpu, cuda, auto or reference.")] = "cpu",
    planner: Annotated[
        str,
        typer.Option("--planner", "--mode", help=f"Registry planner: {PLANNER_NAMES}."),
    ] = "eds",
    out: Annotated[Path, typer.Option(help="Picture of the walk.")] = Path("out/demo.png"),
    sensor: Annotated[
        str,
        typer.Option(
            help="With the daemon, what makes the map: map (the truth in range) or camera "
            "(rendered RGB-D frames through the mapper, people walking)."
        ),
    ] = "map",
    people: Annotated[int, typer.Option(help="With --sensor camera: people walking.")] = 3,
    belt: Annotated[
        str,
        typer.Option(
            help="With the daemon, the belt in the loop: simavr (the firmware on a "
            "simulated Nano), mock (Python mock firmware) or none."
        ),
    ] = "none",
) -> None:
    """Guide a simulated pedestrian across the courtyard and save a picture of the walk."""
    if belt not in ("simavr", "mock", "none"):
        raise typer.BadParameter(f"--belt must be simavr, mock or none, not {belt!r}")
    if sensor not in ("map", "camera"):
        raise typer.BadParameter(f"--sensor must be map or camera, not {sensor!r}")
    if in_process and sensor != "map":
        raise typer.BadParameter("--sensor camera needs the daemon (leave out --in-process)")
    if in_process and belt != "none":
        raise typer.BadParameter("--belt needs the daemon (leave out --in-process)")
    if unknown is None:
        unknown = 0.2 if sensor == "camera" else 0.4  # sim.camera_walk.CAMERA_UNKNOWN says why
    if in_process:
        arrived = run_in_process(grid, unknown, seed, backend, planner, out)
    else:
        from cli.demo_world import run_with_daemon

        arrived = run_with_daemon(
            grid, unknown, seed, backend, follow, out, belt, pace, planner, sensor, people
        )
    raise typer.Exit(0 if arrived else 1)


def register(app: typer.Typer) -> None:
    app.command("demo")(demo)
