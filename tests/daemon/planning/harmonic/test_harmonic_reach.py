"""``Reach`` (which free cells the goal reaches, kept up per change) against a fresh search of
the map after every change: blobs in the open (their contacts join along the ring round them),
rings that close a pocket off, walls that cut the map in two, and the cells freed again."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from daemon.planning.harmonic.reach import Reach, _reached

pytestmark = pytest.mark.timeout(60)


def padded(blocked: np.ndarray) -> np.ndarray:
    out = np.ones((blocked.shape[0] + 2, blocked.shape[1] + 2), dtype=np.bool_)
    out[1:-1, 1:-1] = blocked
    return out.reshape(-1)


def reach_on(blocked: np.ndarray, goal: tuple[int, int]) -> Reach:
    """A ``Reach`` of ``blocked`` with its one-cell border, for ``goal`` (a map cell)."""
    w = blocked.shape[1]
    return Reach(padded(blocked), (goal[0] + 1) * (w + 2) + goal[1] + 1, w + 2)


def pad(cells: np.ndarray, w: int) -> np.ndarray:
    """Map cells of a map ``w`` wide as cells of its padded map."""
    return (cells // w + 1) * (w + 2) + cells % w + 1


def assert_fresh(reach: Reach, maps, blocked: np.ndarray, goal: tuple[int, int]) -> None:
    """``reach`` is what a fresh search of ``blocked`` from ``goal`` finds, and counts it."""
    fresh = padded(~maps.reachable(blocked, goal) | blocked)
    assert (reach.reach == ~fresh).all() and reach.count == int(reach.reach.sum())


def shape_cells(rng: np.random.Generator, h: int, w: int) -> np.ndarray:
    """A blob, a ring (the pocket inside it cut off) or a wall across, as map cells."""
    r, c = int(rng.integers(0, h)), int(rng.integers(0, w))
    size = int(rng.integers(1, 6))
    rr, cc = np.mgrid[0:h, 0:w]
    d = np.maximum(np.abs(rr - r), np.abs(cc - c))
    kind = int(rng.integers(0, 3))
    if kind == 0:
        mask = d <= size
    elif kind == 1:
        mask = d == size
    else:
        mask = (rr == r) if rng.random() < 0.5 else (cc == c)
    return np.flatnonzero(mask.reshape(-1))


def host_search(blocked: np.ndarray, before: np.ndarray, goal: int, width: int) -> np.ndarray:
    """A ``Reach.search`` as the GPU engine's answers: the cells whose reach differs from
    ``before`` in a fresh search of ``blocked``, sorted."""
    fresh = np.zeros(blocked.size, dtype=np.bool_)
    _reached(blocked, goal, width, fresh, np.empty(blocked.size, dtype=np.int64))
    return np.flatnonzero(fresh != before)


@settings(
    max_examples=40, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture]
)
@given(seed=st.integers(0, 2**31), h=st.integers(4, 40), w=st.integers(4, 40),
       density=st.floats(0.0, 0.3), elsewhere=st.booleans())  # fmt: skip
def test_reach_is_the_fresh_search_after_every_change(maps, seed, h, w, density, elsewhere):
    # elsewhere: the whole-map search handed to ``Reach.search`` (the GPU engine's), whose
    # changed cells ``apply`` turns into the same mask, count, lost and gained.
    rng = np.random.default_rng(seed)
    blocked = maps.random_map(rng, h, w, density)
    goal = (int(rng.integers(0, h)), int(rng.integers(0, w)))
    blocked[goal] = False
    reach = reach_on(blocked, goal)
    if elsewhere:
        reach.search = lambda b, before, g: host_search(b, before, g, w + 2)
    for _ in range(6):
        cells = shape_cells(rng, h, w)
        values = np.full(cells.size, rng.random() < 0.75)
        before = reach.reach.copy()
        lost, gained = reach.apply(pad(cells, w), values)
        blocked.reshape(-1)[cells] = values
        fresh = padded(~maps.reachable(blocked, goal) | blocked)
        assert (reach.reach == ~fresh).all()
        assert reach.count == int(reach.reach.sum())
        # What apply reports changed is what changed (the newly blocked count as lost).
        assert set(gained.tolist()) == set(np.flatnonzero(~before & reach.reach).tolist())
        assert set(np.flatnonzero(before & ~reach.reach).tolist()) <= set(lost.tolist())


def test_a_ring_that_closes_a_pocket_is_found_without_the_whole_map(maps):
    # A ring: its contacts inside and outside do not join in the window round it, and the
    # pocket inside is found from the ring (both sides searched ~20 cells deep), not by a
    # search of the map.
    h = w = 300
    blocked = np.zeros((h, w), dtype=bool)
    goal = (5, 5)
    reach = reach_on(blocked, goal)
    rr, cc = np.mgrid[0:h, 0:w]
    d = np.maximum(np.abs(rr - 150), np.abs(cc - 150))
    ring = np.flatnonzero((d == 20).reshape(-1))
    lost, gained = reach.apply(pad(ring, w), np.ones(ring.size, bool))
    blocked.reshape(-1)[ring] = True
    assert reach.cut_searches == 1 and reach.full_searches == 0
    assert_fresh(reach, maps, blocked, goal)
    pocket = (d < 20).sum()
    assert lost.size == ring.size + pocket and gained.size == 0
    # A wall across the goal's own side of the map leaves the goal's region finite: the
    # whole-map search follows, and is right.
    wall = np.flatnonzero((cc == 20).reshape(-1))
    reach.apply(pad(wall, w), np.ones(wall.size, bool))
    blocked.reshape(-1)[wall] = True
    assert_fresh(reach, maps, blocked, goal)


def test_a_try_with_more_seeds_than_its_budget_gives_up_before_it_searches(maps):
    # 16 rings at once on a 120² map: ~3 000 contacts, past the cut-off search's budget
    # (1/8 of the padded map, 1 860 cells). The try ends after its seeds, leaves its scratch
    # zeroed, and the whole-map search finds the 16 pockets.
    h = w = 120
    blocked = np.zeros((h, w), dtype=bool)
    goal = (0, 0)
    reach = reach_on(blocked, goal)
    rr, cc = np.mgrid[0:h, 0:w]
    rings = np.zeros((h, w), dtype=bool)
    for r in range(15, h, 30):
        for c in range(15, w, 30):
            rings |= np.maximum(np.abs(rr - r), np.abs(cc - c)) == 12
    cells = np.flatnonzero(rings.reshape(-1))
    lost, gained = reach.apply(pad(cells, w), np.ones(cells.size, bool))
    blocked |= rings
    assert reach.full_searches == 1 and reach.cut_searches == 0
    assert not reach._group.any()
    assert_fresh(reach, maps, blocked, goal)
    assert lost.size == cells.size + 16 * 23 * 23 and gained.size == 0
