"""``guidebelt compare``: every planner on the same closed-loop walks, one table, one figure.

Only typer and the standard library are imported at the top, the rest inside the command.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Annotated

import typer

from cli.options import PLANNER_NAMES, Backend, Scenarios, Unknowns, comma_list, walk_progress


def compare(
    planners: Annotated[
        str, typer.Option(help=f"Planners, comma separated: {PLANNER_NAMES}.")
    ] = "eds,dss,astar,extended-astar",
    scenario: Scenarios = "courtyard",
    grid: Annotated[str, typer.Option(help="Grid sides, comma separated (100: 10 cm).")] = (
        "100,200"
    ),
    unknown: Unknowns = "0.2,0.4,0.6",
    backend: Backend = "cpu",
    seed: Annotated[int, typer.Option(help="Scenario seed.")] = 0,
    repeats: Annotated[int, typer.Option(min=1, help="Walks per planner and world.")] = 1,
    max_steps: Annotated[
        int | None, typer.Option(min=1, help="Stop each walk after N steps.")
    ] = None,
    json_out: Annotated[Path | None, typer.Option("--json", help="Write the rows here.")] = None,
    plot: Annotated[Path | None, typer.Option(help="Save the four-panel figure here.")] = None,
) -> None:
    """Walk each planner on the same worlds: arrival, metres, turns, ms per step, work done."""
    from rich import box
    from rich.console import Console
    from rich.table import Table

    from sim.compare import COMPARE_HEADS, CompareConfig, plot_compare, run_compare, table_cells
    from sim.scenarios import scenario_list

    try:
        config = CompareConfig(
            planners=comma_list(planners, str),
            grids=comma_list(grid, int),
            unknowns=comma_list(unknown, float),
            scenarios=scenario_list(scenario),
            backend=backend,
            seed=seed,
            repeats=repeats,
            max_steps=max_steps,
        )
        config.check()
    except ValueError as exc:
        raise typer.BadParameter(str(exc)) from exc
    console = Console()
    if not console.is_terminal:  # a log or a pipe: the whole table, not 80 clipped columns
        console = Console(width=160)
    with walk_progress(console) as progress:
        task = progress.add_task("walks", total=config.total_walks())
        rows, device = run_compare(
            config, on_walk=lambda label: progress.update(task, advance=1, description=label)
        )
    table = Table(title=f"planners on the same walks ({device})", box=box.SIMPLE_HEAD)
    for name in COMPARE_HEADS:
        table.add_column(name.replace(" ", "\n"), justify="right", no_wrap=True)
    for cells in table_cells(rows):
        table.add_row(*cells)
    console.print(table)
    if json_out is not None:
        json_out.parent.mkdir(parents=True, exist_ok=True)
        json_out.write_text(json.dumps(rows, indent=1) + "\n")
        console.print(f"rows written to {json_out}")
    if plot is not None:
        plot.parent.mkdir(parents=True, exist_ok=True)
        plot_compare(rows, plot, device)
        console.print(f"plot written to {plot}")


def register(app: typer.Typer) -> None:
    app.command("compare")(compare)
