"""Fixtures the harmonic tests share (maps as functions): random blocks, and a serpentine
corridor where ``1 − u`` falls below what a float holds."""

from __future__ import annotations

import itertools

import numpy as np
import pytest

from daemon.planning.harmonic import relax as rx


def random_map(rng: np.random.Generator, h: int, w: int, density: float) -> np.ndarray:
    blocked = rng.random((h, w)) < density
    # Blobs as well as single cells: pockets, corner-only gaps and dead ends all occur.
    for _ in range(int(rng.integers(0, 4))):
        r, c = int(rng.integers(0, h)), int(rng.integers(0, w))
        blocked[r : r + int(rng.integers(1, 4)), c : c + int(rng.integers(1, 6))] = True
    return blocked


def walled_map(
    rng: np.random.Generator, side: int, density: float, goal: tuple, start: tuple
) -> np.ndarray:
    """``random_map`` inside a wall, with the goal and start cells open (the band's maps)."""
    blocked = random_map(rng, side, side, density)
    blocked[0, :] = blocked[-1, :] = blocked[:, 0] = blocked[:, -1] = True
    blocked[goal] = blocked[start] = False
    return blocked


def segments_free(blocked: np.ndarray, pts: np.ndarray) -> bool:
    """Whether each segment between consecutive band points stays off blocked cells (sampled
    50 times a segment, points in cell units with cell centres at +0.5)."""
    for a, b in itertools.pairwise(pts):
        for t in np.linspace(0.0, 1.0, 50):
            r, c = np.floor(a + t * (b - a)).astype(int)
            if blocked[r, c]:
                return False
    return True


def serpentine(side: int, lane: int = 3, wall: int = 1) -> tuple[np.ndarray, tuple, tuple]:
    """A corridor ``lane`` cells wide that winds from the bottom to the top of a ``side`` map:
    walls across the map with a gap at alternate ends. Returns (blocked, start, goal)."""
    blocked = np.zeros((side, side), dtype=bool)
    blocked[0, :] = blocked[-1, :] = blocked[:, 0] = blocked[:, -1] = True
    row, left = lane + 1, True
    while row < side - 1:
        blocked[row : row + wall, :] = True
        gap = slice(1, 1 + lane) if left else slice(side - 1 - lane, side - 1)
        blocked[row : row + wall, gap] = False
        row += lane + wall
        left = not left
    return blocked, (side - 2, side // 2), (1, side // 2)


def reachable(blocked: np.ndarray, goal: tuple) -> np.ndarray:
    """8-connected reachability from the goal, (h, w) bool."""
    h, w = blocked.shape
    padded = np.ones((h + 2, w + 2), dtype=np.bool_)
    padded[1:-1, 1:-1] = blocked
    steps = np.empty(padded.size, dtype=np.int64)
    rx.bfs_steps(padded.reshape(-1), (goal[0] + 1) * (w + 2) + goal[1] + 1, w + 2, steps)
    return steps.reshape(h + 2, w + 2)[1:-1, 1:-1] >= 0


def flat_reachable(flat: np.ndarray, goal: int, width: int) -> np.ndarray:
    """The plain breadth-first search's reach (8-connected) of a padded flat map, bool."""
    steps = np.empty(flat.size, dtype=np.int64)
    rx.bfs_steps(flat, goal, width, steps)
    return steps >= 0


def descents_hold(planner, blocked: np.ndarray, reach: np.ndarray, steps: bool = False) -> None:
    """From every free cell: a descent to the goal through free cells where the goal is
    reachable, no path where it is not; ``steps``: and each move is to a neighbour."""
    for r, c in zip(*np.nonzero(~blocked), strict=True):
        path = planner.path((r, c))
        if not reach[r, c]:
            assert len(path) == 0
            continue
        assert tuple(path[0]) == (r, c) and tuple(path[-1]) == planner.goal
        assert not blocked[path[:, 0], path[:, 1]].any()
        if steps:
            assert (np.abs(np.diff(path, axis=0)).max(axis=1) == 1).all()


@pytest.fixture
def maps():
    """The map makers above, for tests (``--import-mode=importlib`` imports no sibling)."""
    from types import SimpleNamespace

    return SimpleNamespace(
        random_map=random_map,
        walled_map=walled_map,
        segments_free=segments_free,
        serpentine=serpentine,
        reachable=reachable,
        flat_reachable=flat_reachable,
        descents_hold=descents_hold,
    )
