"""Option parsing shared by the sub-commands."""

from __future__ import annotations

import typer

PLANNER_NAMES = "eds, dss, astar, extended-astar, ga-astar, visgraph"
"""The registry's planners (``daemon.planning.registry.PLANNERS``), for help texts: a
command module does not import the registry at the top (``cli/app.py``);
``tests/cli`` checks the two agree."""


def comma_list(text: str, kind: type) -> list:
    """``"100,200"`` → ``[100, 200]``; a bad item is the user's error, said as such."""
    try:
        return [kind(x) for x in text.split(",") if x.strip()]
    except ValueError as exc:
        raise typer.BadParameter(f"{text!r}: {exc}") from exc
