"""``guidebelt render``: one simulated walk drawn like the paper's Figure 5."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer


def render(
    scenario: Annotated[
        str, typer.Option(help="courtyard, explore, building or streets (see bench).")
    ] = "courtyard",
    grid: Annotated[int, typer.Option(help="Grid side (100 = 10 cm cells).")] = 100,
    unknown: Annotated[float, typer.Option(help="Fraction of free area unknown.")] = 0.4,
    seed: Annotated[int, typer.Option(help="Scenario seed.")] = 0,
    backend: Annotated[str, typer.Option(help="cpu, cuda, auto or reference.")] = "cpu",
    mode: Annotated[str, typer.Option(help="eds or dss (both walk the same cells).")] = "eds",
    fov: Annotated[float, typer.Option(help="Sensor field of view, degrees.")] = 80.0,
    out: Annotated[Path, typer.Option(help="PNG to write.")] = Path("walk.png"),
) -> None:
    """Walk one scenario and save a picture of the map, what was seen and the path walked."""
    from sim.render import render_walk
    from sim.scenarios import make_scenario
    from sim.walk import walk

    if mode not in ("eds", "dss"):
        raise typer.BadParameter("choose eds or dss", param_hint="--mode")
    try:
        world = make_scenario(scenario, grid, unknown, seed)
    except ValueError as exc:
        raise typer.BadParameter(str(exc), param_hint="--scenario or --grid") from exc
    result = walk(world, backend=backend, mode=mode, fov_deg=fov)
    out.parent.mkdir(parents=True, exist_ok=True)
    render_walk(world, result, out)
    typer.echo(
        f"{result.reason}: {result.steps} steps, path {result.walked_m:.1f} m; picture in {out}"
    )


def register(app: typer.Typer) -> None:
    app.command("render")(render)
