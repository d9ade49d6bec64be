"""``guidebelt render``: one simulated walk drawn like the paper's Figure 5."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer


def render(
    grid: Annotated[int, typer.Option(help="Grid side (100 = 10 cm cells).")] = 100,
    unknown: Annotated[float, typer.Option(help="Fraction of free area unknown.")] = 0.4,
    seed: Annotated[int, typer.Option(help="Scenario seed.")] = 0,
    backend: Annotated[str, typer.Option(help="cpu, cuda, auto or reference.")] = "cpu",
    mode: Annotated[str, typer.Option(help="eds or dss (both walk the same cells).")] = "eds",
    fov: Annotated[float, typer.Option(help="Sensor field of view, degrees.")] = 80.0,
    out: Annotated[Path, typer.Option(help="PNG to write.")] = Path("walk.png"),
) -> None:
    """Walk one scenario and save a picture of the map, what was seen and the path walked."""
    from sim.courtyard import make_courtyard
    from sim.render import render_walk
    from sim.walk import walk

    if mode not in ("eds", "dss"):
        raise typer.BadParameter("choose eds or dss", param_hint="--mode")
    scenario = make_courtyard(grid=grid, unknown=unknown, seed=seed)
    result = walk(scenario, backend=backend, mode=mode, fov_deg=fov)
    out.parent.mkdir(parents=True, exist_ok=True)
    render_walk(scenario, result, out)
    typer.echo(
        f"{result.reason}: {result.steps} steps, path {result.walked_m:.1f} m; picture in {out}"
    )


def register(app: typer.Typer) -> None:
    app.command("render")(render)
