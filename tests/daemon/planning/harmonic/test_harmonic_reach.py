"""``Reach`` (which free cells the goal reaches, kept up per change) against a fresh search of
the map after every change: blobs in the open (their contacts join along the ring round them),
rings that close a pocket off, walls that cut the map in two, and the cells freed again."""

from __future__ import annotations

import resource

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from daemon.planning.harmonic import reach as rmod
from daemon.planning.harmonic.floods import free_runs, reached_runs
from daemon.planning.harmonic.reach import MARGIN, Reach, _joined_each
from daemon.planning.harmonic.relax import bfs_steps

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


def bfs_reach(flat: np.ndarray, goal: int, width: int) -> np.ndarray:
    """The plain breadth-first search's reach (8-connected) of a padded flat map."""
    steps = np.empty(flat.size, dtype=np.int64)
    bfs_steps(flat, goal, width, steps)
    return steps >= 0


def host_search(blocked: np.ndarray, before: np.ndarray, goal: int, width: int) -> np.ndarray:
    """A ``Reach.search``'s answer as the GPU engine gives it: the cells whose reach differs
    from ``before`` in a fresh search of ``blocked``, in no set order (its compaction's)."""
    changed = np.flatnonzero(bfs_reach(blocked, goal, width) != before)
    return np.random.default_rng(changed.size).permutation(changed)


def started(changed: np.ndarray):
    """What ``Reach.search`` returns: the wait for an answer found from the masks as they
    were when the search started (the device copies them up before the host goes on)."""
    return lambda: changed


@settings(
    max_examples=40, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture]
)
@given(seed=st.integers(0, 2**31), h=st.integers(4, 40), w=st.integers(4, 40),
       density=st.floats(0.0, 0.3), elsewhere=st.booleans(), whole=st.booleans())  # fmt: skip
def test_reach_is_the_fresh_search_after_every_change(
    maps, monkeypatch, seed, h, w, density, elsewhere, whole
):
    # elsewhere: the whole-map search handed to ``Reach.search`` (the GPU engine's), whose
    # changed cells ``apply`` turns into the same mask, count, lost and gained; whole: the
    # host's cut-off try given no budget, so every change that may cut cells off takes the
    # host's whole-map search (``floods.reached_runs``).
    monkeypatch.setattr(rmod, "HOST_CUT_SHARE", (h + 2) * (w + 2) + 1 if whole else 64)
    rng = np.random.default_rng(seed)
    blocked = maps.random_map(rng, h, w, density)
    goal = (int(rng.integers(0, h)), int(rng.integers(0, w)))
    blocked[goal] = False
    reach = reach_on(blocked, goal)
    if elsewhere:
        reach.search = lambda b, before, g: started(host_search(b, before, g, w + 2))
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
    # pocket inside is found from the ring (both sides searched ~8 cells deep, within the
    # host's budget of 1/64 of the map), not by a search of the map.
    h = w = 300
    blocked = np.zeros((h, w), dtype=bool)
    goal = (5, 5)
    reach = reach_on(blocked, goal)
    rr, cc = np.mgrid[0:h, 0:w]
    d = np.maximum(np.abs(rr - 150), np.abs(cc - 150))
    ring = np.flatnonzero((d == 8).reshape(-1))
    lost, gained = reach.apply(pad(ring, w), np.ones(ring.size, bool))
    blocked.reshape(-1)[ring] = True
    assert reach.cut_searches == 1 and reach.full_searches == 0
    assert_fresh(reach, maps, blocked, goal)
    pocket = (d < 8).sum()
    assert lost.size == ring.size + pocket and gained.size == 0
    # A ring round a pocket of 39² needs more than the host's try may search (1/8 would
    # have done): the whole-map search, by spans, costs less than such a try.
    big = np.flatnonzero((np.maximum(np.abs(rr - 200), np.abs(cc - 200)) == 20).reshape(-1))
    reach.apply(pad(big, w), np.ones(big.size, bool))
    blocked.reshape(-1)[big] = True
    assert reach.cut_searches == 1 and reach.full_searches == 1
    assert_fresh(reach, maps, blocked, goal)
    # A wall across the goal's own side of the map leaves the goal's region finite: the
    # whole-map search follows, and is right.
    wall = np.flatnonzero((cc == 20).reshape(-1))
    reach.apply(pad(wall, w), np.ones(wall.size, bool))
    blocked.reshape(-1)[wall] = True
    assert_fresh(reach, maps, blocked, goal)


def test_a_try_with_more_seeds_than_its_budget_gives_up_before_it_searches(maps):
    # 16 rings at once on a 120² map: ~3 000 contacts, past the cut-off search's budget
    # (1/64 of the padded map on the host, 232 cells). The try ends after its seeds, leaves
    # its scratch zeroed, and the whole-map search finds the 16 pockets.
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


def test_the_clusters_that_fail_list_their_contacts_once_for_the_cut_off_search(maps):
    # Two rings one free column apart (each closes a pocket: its contacts inside and outside
    # do not join) and a blob in the open (its contacts join): the seeds listed are the
    # rings' reached free neighbours, the column between them once, none of the blob's; the
    # scratch is left zeroed.
    h = w = 60
    reach = reach_on(np.zeros((h, w), dtype=bool), (1, 1))
    rr, cc = np.mgrid[0:h, 0:w]
    rings = (np.maximum(np.abs(rr - 20), np.abs(cc - 20)) == 5) | (
        np.maximum(np.abs(rr - 20), np.abs(cc - 32)) == 5
    )
    blob = np.maximum(np.abs(rr - 45), np.abs(cc - 45)) <= 2
    new = pad(np.flatnonzero((rings | blob).reshape(-1)), w)
    reach.blocked[new] = True  # as ``apply``'s flips leave them
    reach.reach[new] = False
    contacts = np.empty(reach.blocked.size, dtype=np.int64)
    n = _joined_each(reach.blocked, reach.reach, new, w + 2, h + 2, MARGIN, reach._mark,
                     reach._queue, reach._label, contacts, reach._out)  # fmt: skip
    ring_cells = padded(rings)
    ring_cells[padded(np.zeros((h, w), dtype=bool))] = False  # the border is not a ring
    near = np.zeros_like(ring_cells)
    for o in (-w - 3, -w - 2, -w - 1, -1, 1, w + 1, w + 2, w + 3):
        near |= np.roll(ring_cells, o)
    want = np.flatnonzero(near & reach.reach)
    assert n == want.size == np.unique(contacts[:n]).size
    assert set(contacts[:n].tolist()) == set(want.tolist())
    assert not reach._label.any() and not reach._mark.any()


def test_beside_a_search_a_long_try_runs_while_the_search_it_started_works(maps):
    # Beside ``Reach.search``, a try first gets 1/FIRST_TRY_SHARE of its budget. A ring whose
    # pocket needs more starts the search (from the reach before the change) and still finds
    # the pocket itself; a wall across the map, which no budget clears, waits for the
    # search's answer. Each ends with the one try's outcome: the same reach and counts.
    h = w = 100
    blocked = np.zeros((h, w), dtype=bool)
    goal = (2, 2)
    reach = Reach(padded(blocked), (goal[0] + 1) * (w + 2) + goal[1] + 1, w + 2)
    started, waited = [], []

    def search(b, before, g):
        started.append(before.copy())  # the masks as the device would have copied them up
        changed = host_search(b, before, g, w + 2)
        return lambda: waited.append(g) or changed

    reach.search = search
    rr, cc = np.mgrid[0:h, 0:w]
    ring = np.flatnonzero((np.maximum(np.abs(rr - 60), np.abs(cc - 60)) == 8).reshape(-1))
    wall = np.flatnonzero((rr == 30).reshape(-1))
    for cells, cut, full in ((ring, 1, 0), (wall, 1, 1)):
        before = reach.reach.copy()
        lost, gained = reach.apply((cells // w + 1) * (w + 2) + cells % w + 1,
                                   np.ones(cells.size, bool))  # fmt: skip
        blocked.reshape(-1)[cells] = True
        fresh = padded(~maps.reachable(blocked, goal) | blocked)
        assert (reach.reach == ~fresh).all() and reach.count == int(reach.reach.sum())
        assert set(np.flatnonzero(before & ~reach.reach).tolist()) == set(lost.tolist())
        assert gained.size == 0 and not reach._group.any()
        assert (reach.cut_searches, reach.full_searches) == (cut, full)
        assert np.array_equal(started[-1], before)  # started from the reach before the change
    assert len(started) == 2 and len(waited) == 1


def scratch(runs: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``reached_runs``'s scratch for ``runs`` runs: their bounds and joins, flags, stack."""
    return np.zeros((4, runs), np.int32), np.zeros(runs, np.int8), np.zeros(runs, np.int32)


def door_steps(rng: np.random.Generator, h: int, w: int) -> list[tuple[np.ndarray, bool]]:
    """A wall across with a door in it (built, the door opened), then the door closing: the
    map cut in two by cells that are never newly blocked all at once."""
    r = int(rng.integers(0, h))
    wall = r * w + np.arange(w)
    door = wall[int(rng.integers(0, w)) :][: int(rng.integers(1, 4))]
    return [(wall, True), (door, False), (door, True)]


@settings(
    max_examples=60, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture]
)
@given(seed=st.integers(0, 2**31), h=st.integers(1, 40), w=st.integers(1, 40),
       density=st.floats(0.0, 0.6))  # fmt: skip
def test_the_search_over_runs_is_the_breadth_first_search_after_every_change(
    maps, seed, h, w, density
):
    # ``reached_runs`` after blobs, rings (a pocket cut off), walls, doors closing and cells
    # freed, from the reach before each change: the plain BFS's reach and count, and the cells
    # lost and gained in map order (the newly blocked the goal reached among the lost). A
    # change that frees no cell reads one cell a run for its old reach (``split_only``).
    rng = np.random.default_rng(seed)
    blocked = maps.random_map(rng, h, w, density)
    goal = (int(rng.integers(0, h)), int(rng.integers(0, w)))
    width = w + 2
    g = (goal[0] + 1) * width + goal[1] + 1
    flat = padded(blocked)
    reach = bfs_reach(flat, g, width)
    changes = [(shape_cells(rng, h, w), rng.random() < 0.7) for _ in range(4)]
    goal_cell = np.array([goal[0] * w + goal[1]])
    changes += [*door_steps(rng, h, w), (goal_cell, True), (goal_cell, False)]
    for cells, value in changes:
        cells = pad(cells, w)
        freed = bool((flat[cells] & ~value).any())
        before = reach.copy()
        now_blocked = cells[~flat[cells] & value]
        flat[cells] = value
        reach[now_blocked] = False
        lost, gained = np.empty(flat.size, np.int64), np.empty(flat.size, np.int64)
        args = (flat, g, width, reach, np.sort(now_blocked[before[now_blocked]]), not freed)
        # Scratch for one run at first: the search says how many it needs, reach untouched.
        count, n_lost, n_gained = reached_runs(*args, *scratch(1), lost, gained)
        n = free_runs(flat, np.empty(flat.size, np.int32), np.empty(flat.size, np.int32))
        if n > 1:
            assert count == -n and np.array_equal(reach, before & ~flat)
            count, n_lost, n_gained = reached_runs(*args, *scratch(n), lost, gained)
        fresh = bfs_reach(flat, g, width)
        assert np.array_equal(reach, fresh) and count == int(fresh.sum())
        assert np.array_equal(lost[:n_lost], np.flatnonzero(before & ~fresh))
        assert np.array_equal(gained[:n_gained], np.flatnonzero(~before & fresh))


def test_the_runs_are_the_rows_free_stretches_at_any_length():
    # The map's bytes are read eight at a time: runs that start or end on a word's edge, in the
    # last few cells past the last whole word, and a map of fewer than eight cells.
    rng = np.random.default_rng(7)
    for size in (3, 7, 8, 9, 15, 16, 17, 63, 64, 65, 333):
        flat = rng.random(size) < 0.4
        flat[0] = flat[-1] = True
        edges = np.flatnonzero(np.diff(flat.astype(np.int8)))
        starts, ends = np.zeros(size, np.int32), np.zeros(size, np.int32)
        n = free_runs(flat, starts, ends)
        assert n == edges.size // 2
        assert np.array_equal(starts[:n], edges[0::2] + 1) and np.array_equal(ends[:n], edges[1::2])


def test_the_scratch_is_mapped_at_construction_not_by_the_first_sweep():
    """A sweep's changes spread over the map write ``_label`` and ``_mark`` on every page, and
    a pocket closed in the same sweep runs the cut-off search: the pages are the kernel's to
    fault in at construction, not inside the first step."""
    h = w = 1024
    blocked = np.zeros((h, w), dtype=bool)
    goal = (h // 2, w // 2)
    warm = reach_on(blocked[:64, :64], (32, 32))  # numba's compile or cache load, outside
    warm.apply(pad(np.array([5 * 64 + 5]), 64), np.ones(1, dtype=bool))
    reach = reach_on(blocked, goal)
    # One isolated new obstacle every 4 rows (each 4 KiB page of the masks holds ~4 rows),
    # a ring round a pocket, and a 200² block (its 40 k cells fill the lists' fronts).
    scattered = np.array([r * w + (r * 37) % (w - 2) + 1 for r in range(2, h - 2, 4)])
    rr, cc = np.mgrid[0:h, 0:w]
    d = np.maximum(np.abs(rr - 100), np.abs(cc - 900)).reshape(-1)
    ring = np.flatnonzero(d == 20)
    block = np.flatnonzero(((rr >= 700) & (rr < 900) & (cc >= 100) & (cc < 300)).reshape(-1))
    cells = np.union1d(np.union1d(scattered, ring), block)
    before = resource.getrusage(resource.RUSAGE_SELF).ru_minflt
    lost, gained = reach.apply(pad(cells, w), np.ones(cells.size, dtype=bool))
    faults = resource.getrusage(resource.RUSAGE_SELF).ru_minflt - before
    assert reach.cut_searches == 1 and reach.full_searches == 0
    assert lost.size == cells.size + (d < 20).sum() and gained.size == 0
    # Mapped on first write: 830–1 050 faults here, ~190 of them the lists' fronts (dev VM;
    # fewer where transparent huge pages serve the lists, 8 MB each).
    assert faults < 64
