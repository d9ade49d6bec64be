"""Reachability kept by ``Reach.apply``: a change the connectivity windows cannot clear is
cleared from the last field's Idx (``_proven``) without the whole-map search when nothing was
cut off, and the reached set always equals a fresh search, whatever Idx holds."""

from __future__ import annotations

import numpy as np
import pytest

from daemon.planning.harmonic import reach as reach_module
from daemon.planning.harmonic.reach import MARGIN, Reach
from daemon.planning.harmonic.relax import bfs_steps

pytestmark = pytest.mark.timeout(60)


def padded(blocked: np.ndarray) -> np.ndarray:
    out = np.ones((blocked.shape[0] + 2, blocked.shape[1] + 2), dtype=np.bool_)
    out[1:-1, 1:-1] = blocked
    return out.reshape(-1)


def flat(cell: tuple[int, int], width: int) -> int:
    return (cell[0] + 1) * (width + 2) + cell[1] + 1


def descent_idx(blocked: np.ndarray, goal: int, width: int) -> np.ndarray:
    """Idx that falls along BFS steps to the goal (what a field without a pit gives)."""
    steps = np.empty(blocked.size, dtype=np.int64)
    bfs_steps(blocked, goal, width, steps)
    idx = np.full(blocked.size, 4, dtype=np.int8)
    for i in np.flatnonzero(steps > 0):
        for d in range(9):
            j = i + (d // 3 - 1) * width + d % 3 - 1
            if steps[j] == steps[i] - 1:
                idx[i] = d
                break
    return idx


def fresh_reach(blocked: np.ndarray, goal: int, width: int) -> np.ndarray:
    steps = np.empty(blocked.size, dtype=np.int64)
    bfs_steps(blocked, goal, width, steps)
    return steps >= 0


def detour_map() -> tuple[np.ndarray, tuple[int, int], np.ndarray]:
    """A wall down column 30 with a gap at the top; the change is a new wall across the left
    side at row 60. The left part above it still reaches the goal (bottom left) through the
    gap, a detour far outside the change's window, so the windows cannot clear the change.
    The open right side keeps the room and its detour within ``PROOF_SHARE``'s share."""
    blocked = np.zeros((100, 300), dtype=np.bool_)
    blocked[2:81, 30] = True
    new = np.array([(60, c) for c in range(0, 30)])
    return blocked, (95, 5), new


@pytest.mark.parametrize("with_idx", [True, False])
def test_a_change_the_windows_cannot_clear_is_cleared_from_the_field(with_idx: bool) -> None:
    blocked, goal, new = detour_map()
    width = blocked.shape[1] + 2
    grid = padded(blocked)
    g = flat(goal, blocked.shape[1])
    reach = Reach(grid, g, width)
    idx = descent_idx(grid, g, width) if with_idx else None
    cells = np.array([flat((r, c), blocked.shape[1]) for r, c in new], dtype=np.int64)
    # The old descents from above the new wall cross it: the proof needs the BFS, too.
    assert MARGIN < 60 - 2
    lost, gained = reach.apply(cells, np.ones(cells.size, dtype=np.bool_), idx)
    assert reach.full_searches == (0 if with_idx else 1)
    assert sorted(lost.tolist()) == sorted(cells.tolist()) and gained.size == 0
    assert np.array_equal(reach.reach, fresh_reach(reach.blocked, g, width))
    assert reach.count == int(reach.reach.sum())


def test_a_pocket_cut_off_is_found_by_the_whole_map_search() -> None:
    blocked, goal, new = detour_map()
    blocked[:2, 30] = True  # no gap: the new wall closes the top left room
    width = blocked.shape[1] + 2
    grid = padded(blocked)
    g = flat(goal, blocked.shape[1])
    reach = Reach(grid, g, width)
    cells = np.array([flat((r, c), blocked.shape[1]) for r, c in new], dtype=np.int64)
    lost, _ = reach.apply(cells, np.ones(cells.size, dtype=np.bool_), descent_idx(grid, g, width))
    assert reach.full_searches == 1
    room = {flat((r, c), blocked.shape[1]) for r in range(0, 60) for c in range(30)}
    assert room <= set(lost.tolist())
    assert np.array_equal(reach.reach, fresh_reach(reach.blocked, g, width))


@pytest.mark.parametrize("seed", range(6))
def test_reach_equals_a_fresh_search_whatever_idx_holds(seed: int, monkeypatch) -> None:
    # Random walls and random deltas; Idx a good descent, then noise (int8, out of range too).
    # Windows of one cell fail often, so the proof from Idx decides most changes.
    monkeypatch.setattr(reach_module, "MARGIN", 1)
    proofs = {"tried": 0, "cleared": 0}
    real = reach_module._proven

    def counted(*args):
        proofs["tried"] += 1
        ok = real(*args)
        proofs["cleared"] += bool(ok)
        return ok

    monkeypatch.setattr(reach_module, "_proven", counted)
    rng = np.random.default_rng(seed)
    shape = (40, 40)
    blocked = rng.random(shape) < 0.25
    goal = (20, 20)
    blocked[goal] = False
    width = shape[1] + 2
    grid = padded(blocked)
    g = flat(goal, shape[1])
    reach = Reach(grid, g, width)
    for step in range(40):
        idx = (descent_idx(reach.blocked, g, width) if step % 2 else
               rng.integers(-128, 128, grid.size).astype(np.int8))  # fmt: skip
        # A short wall segment (a cluster), some cells freed, the goal kept free.
        r, c = rng.integers(0, shape[0]), rng.integers(0, shape[1] - 12)
        wall = [(r, c + k) for k in range(rng.integers(3, 12))]
        freed = [tuple(x) for x in rng.integers(0, shape[0], (4, 2))]
        cells = [flat(x, shape[1]) for x in wall + freed if x != goal]
        values = [True] * sum(x != goal for x in wall) + [False] * sum(x != goal for x in freed)
        reach.apply(np.array(cells, dtype=np.int64), np.array(values, dtype=np.bool_), idx)
        assert np.array_equal(reach.reach, fresh_reach(reach.blocked, g, width)), step
        assert reach.count == int(reach.reach.sum())
    assert proofs["cleared"] > 0 and reach.full_searches > 0, proofs
