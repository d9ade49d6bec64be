"""The planner names the help texts list are the registry's, no more and no fewer."""

from __future__ import annotations

from cli.options import PLANNER_NAMES
from daemon.planning.registry import PLANNERS


def test_the_help_texts_name_every_registered_planner() -> None:
    assert PLANNER_NAMES.split(", ") == list(PLANNERS)
