"""Many planners on one device (issue 28): the device's one resident loop serves them all.

Planners of different map sizes and modes step interleaved, each step bit-exact with the
reference Dijkstra, without the loop ever stopping; planners that go away give their slot
back to the next, and a table that fills up grows.
"""

from __future__ import annotations

import gc

import numpy as np
import pytest

from daemon.planning import cuda_available
from daemon.planning.dijkstra import dijkstra_field, reference_path

pytestmark = [
    pytest.mark.gpu,
    pytest.mark.skipif(not cuda_available(), reason="no usable CUDA device"),
    pytest.mark.timeout(180),
]


@pytest.fixture(autouse=True)
def _fresh_loop(monkeypatch):
    from daemon.planning.cuda import resident

    resident.evict()
    monkeypatch.setattr(resident, "_SHARED", None)
    # the reference Dijkstra between steps is slow Python: no idle exit meanwhile
    monkeypatch.setattr(resident, "IDLE_MS", 60_000.0)
    yield resident
    resident.evict()


class User:
    """One planner, its map and goal, and a seeded walk of patches that open and close."""

    def __init__(self, seed: int, shape: tuple[int, int], dss: bool = False) -> None:
        from daemon.planning.cuda.planner import CudaPlanner

        self.rng = np.random.default_rng(seed)
        self.truth = self.rng.random(shape) < 0.25
        h, w = shape
        self.goal = (int(self.rng.integers(h)), int(self.rng.integers(w)))
        self.truth[self.goal] = False
        self.p = CudaPlanner("fast", dss=dss)
        self.p.plan(self.truth, self.goal)

    def step(self) -> None:
        h, w = self.truth.shape
        cy, cx, r = (int(v) for v in self.rng.integers((0, 0, 1), (h, w, 5)))
        ys, xs = np.mgrid[max(cy - r, 0) : min(cy + r + 1, h), max(cx - r, 0) : min(cx + r + 1, w)]
        cells = (ys * w + xs).ravel().astype(np.int64)
        values = self.rng.random(cells.size) < 0.6
        values[cells == self.goal[0] * w + self.goal[1]] = False
        start = (int(self.rng.integers(h)), int(self.rng.integers(w)))
        self.truth.reshape(-1)[cells] = values
        _, path = self.p.update_and_path(cells, values, start)
        g = dijkstra_field(self.truth, self.goal)
        assert np.array_equal(path, reference_path(g, self.truth, start))
        assert np.array_equal(self.p.costs(), g)


def test_planners_of_every_size_step_interleaved_in_one_launch(_fresh_loop):
    """Four planners (one tile, a few tiles, more tiles than the loop has blocks, DSS beside
    EDS) step round-robin; every step is exact and the loop is launched once for all."""
    shapes = [(1, 1), (30, 70), (20, 20), (390, 380)]
    users = [User(s, shape, dss=s == 2) for s, shape in enumerate(shapes)]
    loop = _fresh_loop.active()
    assert loop is not None and loop.attached == 4
    launches = loop.launches
    for _ in range(6):
        for u in users:
            u.step()
    assert _fresh_loop.active() is loop and loop.launches == launches


def test_slots_are_given_back_and_the_table_grows(_fresh_loop):
    """More planners than the table's first size; the ones dropped free their slots, which
    new planners take, and every planner left stays exact."""
    n = _fresh_loop.SLOTS + 6
    users = [User(100 + k, (24, 40)) for k in range(n)]
    loop = _fresh_loop.shared()
    assert loop.attached == n
    for u in users[::7]:
        u.step()
    kept = users[1::2]
    del users, u
    gc.collect()
    assert loop.attached == len(kept)
    fresh = [User(500 + k, (33, 33)) for k in range(3)]
    assert loop.attached == len(kept) + 3
    for u in [*fresh, *kept[::5]]:
        u.step()
