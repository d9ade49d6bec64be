"""A step's relaxation started while the host searches for cells cut off (``HarmonicPlanner``'s
``overlap``): the same field, sweeps and reach as the step run in order, whether the search
finds nothing cut off (the early relaxation stands) or a region (it is undone and run again).
The CUDA engine's own check is ``test_harmonic_overlap_cuda.py``."""

from __future__ import annotations

import numpy as np
import pytest

from daemon.planning.harmonic import HarmonicPlanner
from daemon.planning.harmonic.cpu import CpuField

pytestmark = pytest.mark.timeout(60)

H, W = 48, 120
WALL = 60
"""A wall down column 60 with two doors 30 rows apart: a door's contacts join only through
the other door, outside the window round it (``reach.MARGIN`` 16), so closing one needs a
search; closing both cuts the right half off."""
DOORS = (range(6, 9), range(36, 39))
GOAL = (24, 8)


def door_map() -> np.ndarray:
    blocked = np.zeros((H, W), dtype=bool)
    blocked[:, WALL] = True
    for door in DOORS:
        blocked[door.start : door.stop, WALL] = False
    return blocked


def cells_of(rows: range, col: int) -> np.ndarray:
    return np.array([r * W + col for r in rows], dtype=np.int64)


# (cells, blocked, (early starts that stood, undone) after it) in turn: door A closed (nothing
# cut off, found by a search), a block in the open (its contacts join: no search), door B
# closed (the right half cut off), door A opened (cells freed: no early start), door A closed
# again (the right half cut off again).
STEPS = [
    (cells_of(DOORS[0], WALL), True, (1, 0)),
    (np.array([20 * W + 30, 20 * W + 31, 21 * W + 30], dtype=np.int64), True, (1, 0)),
    (cells_of(DOORS[1], WALL), True, (1, 1)),
    (cells_of(DOORS[0], WALL), False, (1, 1)),
    (cells_of(DOORS[0], WALL), True, (1, 2)),
]


def planner(overlap: bool) -> HarmonicPlanner:
    p = HarmonicPlanner(CpuField())
    p.overlap = overlap
    p.plan(door_map(), GOAL)
    return p


def test_the_early_relaxation_gives_the_ordered_steps_field_to_the_bit() -> None:
    early, ordered = planner(True), planner(False)
    assert np.array_equal(early.field(), ordered.field())
    for cells, value, counts in STEPS:
        a = early.update(cells, np.full(cells.size, value))
        b = ordered.update(cells, np.full(cells.size, value))
        assert (a.iterations, a.cells_touched) == (b.iterations, b.cells_touched)
        assert np.array_equal(early.field(), ordered.field())
        assert np.array_equal(early.reach.reach, ordered.reach.reach)
        assert (early.residual, early.filled, early.settled) == (
            ordered.residual,
            ordered.filled,
            ordered.settled,
        )
        for start in ((40, 100), (2, 2), (24, 70)):
            assert np.array_equal(early.path(start), ordered.path(start))
        assert (early.overlaps, early.undone) == counts
    assert (ordered.overlaps, ordered.undone) == (0, 0)
    assert early.reach.full_searches == ordered.reach.full_searches >= 2


def test_undo_gives_back_the_field_and_fixedness_the_start_found() -> None:
    p = planner(True)
    engine = p.engine
    w, fixed = engine.w.copy(), engine.fixed.copy()
    wait = engine.relax_start(20, 1e-9, 10, keep=True)  # past the plan's tolerance: it sweeps
    assert wait()[0] > 0
    assert not np.array_equal(engine.w, w)
    engine.undo()
    assert np.array_equal(engine.w, w) and np.array_equal(engine.fixed, fixed)
