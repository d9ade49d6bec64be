"""Option parsing shared by the sub-commands."""

from __future__ import annotations

from typing import Annotated

import typer

PLANNER_NAMES = "eds, dss, astar, extended-astar, ga-astar, visgraph, harmonic"
"""The registry's planners (``daemon.planning.registry.PLANNERS``), for help texts: a
command module does not import the registry at the top (``cli/app.py``);
``tests/cli`` checks the two agree."""


def comma_list(text: str, kind: type) -> list:
    """``"100,200"`` → ``[100, 200]``; a bad item is the user's error, said as such."""
    try:
        return [kind(x) for x in text.split(",") if x.strip()]
    except ValueError as exc:
        raise typer.BadParameter(f"{text!r}: {exc}") from exc


# Options that several commands take with the same meaning (bench, compare, walks…).
Scenarios = Annotated[
    str, typer.Option(help="Scenarios, comma separated: courtyard, explore, building, streets.")
]
Unknowns = Annotated[str, typer.Option(help="Fractions of free area unknown.")]
Backend = Annotated[str, typer.Option(help="cpu, cuda, auto or reference.")]


def walk_progress(console):
    """A progress bar of walks (rich imported here: command modules import it lazily)."""
    from rich.progress import BarColumn, MofNCompleteColumn, Progress, TextColumn, TimeElapsedColumn

    return Progress(
        TextColumn("[progress.description]{task.description}"),
        BarColumn(),
        MofNCompleteColumn(),
        TimeElapsedColumn(),
        console=console,
    )
