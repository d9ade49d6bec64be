"""The rule the fast planner's cut-over keeps the old field by (``kernels/cut_over.cuh``),
checked on the CPU against the reference Dijkstra: after a delta, every cell whose old g lies
below the level (the least old g of a newly blocked cell, and STRAIGHT plus the least old g
next to a freed one) keeps its g exactly. The device part (deferred tiles' bounds) is tested
on the GPU (``test_focused_repair.py``, ``always_cut``)."""

from __future__ import annotations

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from daemon.planning.dijkstra import dijkstra_field
from daemon.planning.grid import INF, STRAIGHT


def keep_level(old_g: np.ndarray, cells: np.ndarray, blocked: np.ndarray) -> int:
    """The kernel's level, over a delta of flat cells and their new values."""
    h, w = old_g.shape
    padded = np.full((h + 2, w + 2), INF, np.int64)
    padded[1:-1, 1:-1] = old_g
    level = INF
    for cell, now in zip(cells.tolist(), blocked.tolist(), strict=True):
        y, x = divmod(cell, w)
        if now:
            level = min(level, int(old_g[y, x]))
        else:
            around = padded[y : y + 3, x : x + 3].copy()
            around[1, 1] = INF  # the neighbours, not the cell
            level = min(level, int(around.min()) + STRAIGHT)
    return level


@settings(max_examples=150, deadline=None)
@given(
    h=st.integers(2, 24),
    w=st.integers(2, 24),
    density=st.sampled_from([0.0, 0.15, 0.35]),
    flip=st.sampled_from([0.02, 0.1, 0.3]),
    seed=st.integers(0, 2**32 - 1),
)
def test_cells_below_the_level_keep_their_g_after_any_delta(h, w, density, flip, seed):
    rng = np.random.default_rng(seed)
    old = rng.random((h, w)) < density
    goal = (int(rng.integers(h)), int(rng.integers(w)))
    old[goal] = False
    cells = np.flatnonzero(rng.random(h * w) < flip)
    new_values = rng.random(cells.size) < 0.5  # blocked, freed, or unchanged, mixed
    new = old.copy()
    new.reshape(-1)[cells] = new_values
    old_g, new_g = dijkstra_field(old, goal), dijkstra_field(new, goal)
    level = keep_level(old_g, cells, new_values)
    kept = old_g < level
    np.testing.assert_array_equal(new_g[kept], old_g[kept])
    if not new[goal] and level > 0:
        assert kept[goal]  # the goal is kept unless the change touches it
