"""Every scenario a walk or the benchmark can run, by name: one entry point.

- ``courtyard``: the paper's 10 m courtyard, walls, garden and boxes known, small unknown
  obstacles found on the way (``courtyard.py``).
- ``explore``: the same courtyard's true world, but nothing known at the start: every
  obstacle, the walls included, is found by the 3 m / 80° sensor on the way.
- ``building``: a seeded 20 m floor plan of rooms, corridors and doors; the plan says every
  door is open, some are closed (``building.py``).
- ``streets``: a seeded 40 m city quarter, buildings known, unknown things on the
  pavement (``streets.py``).

All are the same ``Scenario`` (``walk``, the belt walker and the benchmark take any one) and
all are deterministic in ``(grid, unknown, seed)``.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from daemon.planning.grid import UNKNOWN

from . import building, courtyard, streets
from .building import make_building
from .courtyard import Scenario, make_courtyard
from .streets import make_streets

SCENARIOS = ("courtyard", "explore", "building", "streets")


def make_explore(grid: int = 100, unknown: float = 0.4, seed: int = 0) -> Scenario:
    """The courtyard's true world with an all-UNKNOWN known map (walls too are discovered)."""
    courtyard = make_courtyard(grid, unknown, seed)
    return replace(courtyard, known=np.full_like(courtyard.known, UNKNOWN), name="explore")


def make_scenario(name: str, grid: int = 100, unknown: float = 0.4, seed: int = 0) -> Scenario:
    """The scenario ``name`` at ``grid`` cells per side; ValueError for a name not known."""
    if name == "courtyard":
        return make_courtyard(grid, unknown, seed)
    if name == "explore":
        return make_explore(grid, unknown, seed)
    if name == "building":
        return make_building(grid, unknown, seed)
    if name == "streets":
        return make_streets(grid, unknown, seed)
    raise ValueError(f"unknown scenario {name!r}; choose one of {', '.join(SCENARIOS)}")


def check_grid(name: str, grid: int) -> None:
    """ValueError, naming the scenario, unless ``name`` exists and can be drawn at ``grid``.

    Cheap: the benchmark checks every (scenario, grid) before its first walk, not after an
    hour of them.
    """
    if name not in SCENARIOS:
        raise ValueError(f"unknown scenario {name!r}; choose one of {', '.join(SCENARIOS)}")
    if name in ("courtyard", "explore"):
        try:
            courtyard.check_grid(grid)
        except ValueError as exc:
            raise ValueError(f"{name}: {exc}") from None
    else:
        (building if name == "building" else streets).check_grid(grid)


def scenario_list(text: str) -> list[str]:
    """``"courtyard,building"`` → the names, each checked; ValueError names a bad one."""
    names = [n.strip() for n in text.split(",") if n.strip()]
    if not names:
        raise ValueError(f"no scenario in {text!r}; choose from {', '.join(SCENARIOS)}")
    for n in names:
        if n not in SCENARIOS:
            raise ValueError(f"unknown scenario {n!r}; choose from {', '.join(SCENARIOS)}")
    return names
