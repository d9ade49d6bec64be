"""The simulated world in three dimensions: a height interval and a look for every cell.

A ``Scene3D`` gives each map cell an obstacle slab ``[z_lo, z_hi]`` (``z_hi = 0``: nothing)
and a kind that decides its colour: walls, boxes, tables (a top a cane would miss: nothing
below 0.70 m), people, and floor marks (seed 004's green target). ``scene_from_scenario``
lifts any 2-D ``Scenario`` into one: the border is a 2.5 m wall, the known obstacles are
boxes and hedges, and the unknown ones (found on the way) are boxes or tables, seeded.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .courtyard import Scenario

FLOOR, WALL, BOX, TABLE, PERSON = 0, 1, 2, 3, 4
"""Obstacle kinds (``Scene3D.kind``)."""
PLAIN, TARGET = 0, 1
"""Floor marks (``Scene3D.mark``): seed 004's green target on the floor."""

WALL_M = 2.5
TABLE_TOP = (0.70, 0.76)
"""A table's top: a white cane sweeps under it, a chest camera sees it."""
TABLE_SHARE = 0.3
"""Share of unknown obstacles that are tables (the rest are boxes)."""


@dataclass
class Scene3D:
    cell_m: float
    z_lo: np.ndarray
    """``(h, w)`` float32: bottom of each cell's obstacle."""
    z_hi: np.ndarray
    """``(h, w)`` float32: top of each cell's obstacle; 0 where there is none."""
    kind: np.ndarray
    """``(h, w)`` uint8: FLOOR, WALL, BOX, TABLE or PERSON."""
    mark: np.ndarray
    """``(h, w)`` uint8: PLAIN or TARGET floor."""

    @property
    def shape(self) -> tuple[int, int]:
        return (int(self.z_hi.shape[0]), int(self.z_hi.shape[1]))

    def copy(self) -> Scene3D:
        return Scene3D(self.cell_m, self.z_lo.copy(), self.z_hi.copy(), self.kind.copy(),
                       self.mark.copy())  # fmt: skip

    def occupancy(self) -> np.ndarray:
        """The 2-D truth a walker runs into: any obstacle below head height."""
        return (self.z_hi > 0).astype(np.uint8)

    def put(self, cells: tuple[np.ndarray, np.ndarray] | np.ndarray, kind: int, lo: float,
            hi: float) -> None:  # fmt: skip
        self.z_lo[cells], self.z_hi[cells], self.kind[cells] = lo, hi, kind


def empty_scene(shape: tuple[int, int], cell_m: float) -> Scene3D:
    return Scene3D(cell_m, np.zeros(shape, np.float32), np.zeros(shape, np.float32),
                   np.zeros(shape, np.uint8), np.zeros(shape, np.uint8))  # fmt: skip


def scene_from_scenario(scenario: Scenario, seed: int = 0) -> Scene3D:
    """The scenario's true world with heights (see the module docstring), seeded."""
    rng = np.random.default_rng([seed, 3])
    h, w = scenario.shape
    scene = empty_scene((h, w), scenario.cell_m)
    true = scenario.true == 1
    known = scenario.known == 1
    border = np.zeros((h, w), bool)
    border[0, :] = border[-1, :] = border[:, 0] = border[:, -1] = True
    scene.put(true & border, WALL, 0.0, WALL_M)
    fixed = true & known & ~border
    # Known obstacles: each cell a box from 0.5 to 1.2 m (garden hedges, stacked boxes).
    rows, cols = np.nonzero(fixed)
    tops = 0.5 + 0.7 * rng.random(rows.size)
    scene.z_hi[rows, cols], scene.kind[rows, cols] = tops, BOX
    # Unknown ones: a 30 cm block (the blob size) is one box or one table.
    rows, cols = np.nonzero(true & ~known & ~border)
    block = (rows // 3) * 100_003 + cols // 3
    labels, inverse = np.unique(block, return_inverse=True)
    is_table = rng.random(labels.size) < TABLE_SHARE
    top = 0.4 + 0.6 * rng.random(labels.size)
    t = is_table[inverse]
    scene.z_lo[rows[t], cols[t]] = TABLE_TOP[0]
    scene.z_hi[rows[t], cols[t]] = TABLE_TOP[1]
    scene.kind[rows[t], cols[t]] = TABLE
    scene.z_hi[rows[~t], cols[~t]] = top[inverse][~t]
    scene.kind[rows[~t], cols[~t]] = BOX
    return scene
