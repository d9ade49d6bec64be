"""Out of a pocket along the user's own track, and the dead end remembered once left."""

from __future__ import annotations

import itertools

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from daemon.navigation.pocket import Track, track_out
from daemon.navigation.route import Route
from daemon.planning import make_planner
from daemon.planning.grid import FREE, OCCUPIED, UNKNOWN
from daemon.planning.inflation import InflatedMap

RADIUS = 1
GOAL = (2, 2)
DEEP = (15, 1)
"""The user's cell at the pocket's far end: 11 cells from the nearest cell with a path."""
GAP = [(14, 10), (15, 10)]


def box_map() -> InflatedMap:
    """A box (rows 10-20, columns 0-10: the map's edge is its left side) with a gap two
    cells wide in its right wall, which the inflation closes; the goal above the box, behind
    a wall that the box's top continues to column 25."""
    occ = np.full((30, 30), FREE, np.uint8)
    occ[10, :26] = occ[20, :11] = OCCUPIED
    occ[10:21, 10] = OCCUPIED
    for cell in GAP:
        occ[cell] = FREE
    m = InflatedMap(occ, RADIUS)
    assert all(m.blocked[c] for c in GAP)
    return m


def walked_in(route: Route) -> list[tuple[int, int]]:
    """The user came from the right along row 15, through the gap, to the far end."""
    cells = [(15, c) for c in range(25, DEEP[1] - 1, -1)]
    for cell in cells:
        route.track.add(cell)
    return cells


def new_route() -> Route:
    return Route(lambda backend: make_planner("eds", backend), "cpu", RADIUS + 2, RADIUS)


def in_pocket(cell) -> bool:
    return 10 < cell[0] < 20 and cell[1] <= 10


def test_the_way_out_of_a_pocket_is_the_users_own_track_backwards():
    m, route = box_map(), new_route()
    walk = walked_in(route)
    path, cost = route.path_from(m.blocked, m.occupancy, GOAL, DEEP)
    assert route.report.back_along_track
    assert tuple(path[-1]) == GOAL and cost < 10_000
    # Back along row 15 until the first cell with a plan, then round the box to the goal.
    out = [tuple(c) for c in path[: len(walk)]]
    back = walk[::-1]
    k = next(i for i, c in enumerate(out) if c != back[i])
    assert k >= 11 and all(in_pocket(c) or m.blocked[c] for c in back[: k - 1])
    assert all(m.occupancy[tuple(c)] != OCCUPIED for c in path)
    steps = np.abs(np.diff(path, axis=0)).max(axis=1)
    assert steps.max() == 1  # one neighbouring cell at a time


def test_no_way_back_across_a_known_obstacle():
    m, route = box_map(), new_route()
    walked_in(route)
    # A person stands in the gap now: the track is no way out, and nothing else is.
    m.apply(np.array([15 * 30 + 10, 14 * 30 + 10]), np.array([OCCUPIED, OCCUPIED], np.uint8))
    path, _ = route.path_from(m.blocked, m.occupancy, GOAL, DEEP)
    assert len(path) == 0 and not route.report.back_along_track


def test_a_pocket_left_is_not_entered_again_when_its_walls_are_forgotten():
    m, route = box_map(), new_route()
    walked_in(route)
    path, _ = route.path_from(m.blocked, m.occupancy, GOAL, DEEP)
    i = 1
    while route.dead is None and i < 20:  # the user follows the way out
        step, _ = route.path_from(m.blocked, m.occupancy, GOAL, tuple(path[i]))
        assert len(step)
        i += 1
    assert route.dead is not None and all(route.dead[c] for c in GAP)
    assert not route.dead[tuple(path[i - 1])]  # marked once the user stood clear of it
    here = tuple(path[i + 1])
    # The box's top wall and the gap's sides go out of view and are forgotten: the gap and
    # the pocket now look like the short way to the goal.
    gone = np.array([10 * 30 + c for c in range(10)] + [r * 30 + 10 for r in (12, 13, 16, 17)])
    flipped, now = m.apply(gone, np.full(gone.size, UNKNOWN, np.uint8))
    route.change(flipped, now)
    fresh = new_route()
    short, _ = fresh.path_from(m.blocked, m.occupancy, GOAL, here)
    assert any(in_pocket(tuple(c)) for c in short)  # without the memory: back in
    kept, _ = route.path_from(m.blocked, m.occupancy, GOAL, here)
    assert len(kept) and tuple(kept[-1]) == GOAL
    assert not any(in_pocket(tuple(c)) for c in kept)
    # A new goal: the dead end was one goal's; it is forgotten.
    route.forget_dead_ends()
    assert route.dead is None


def test_a_dead_end_that_leaves_no_way_at_all_is_dropped():
    m, route = box_map(), new_route()
    route.dead = np.zeros(m.shape, bool)
    route.dead[:, 15] = True  # a remembered band cutting the user off the goal entirely
    path, _ = route.path_from(m.blocked, m.occupancy, GOAL, (5, 25))
    assert tuple(path[-1]) == GOAL and route.dead is None


@settings(max_examples=60, deadline=None)
@given(st.lists(st.sampled_from([(0, 1), (1, 0), (0, -1), (-1, 0), (1, 1), (-1, -1)]),
                min_size=1, max_size=60))  # fmt: skip
def test_the_track_is_a_loop_free_chain_of_walked_cells(moves):
    track, cell, walked = Track(), (50, 50), {(50, 50)}
    track.add(cell)
    for dr, dc in moves:
        cell = (cell[0] + dr, cell[1] + dc)
        walked.add(cell)
        track.add(cell)
    cells = list(track.cells)
    assert cells[-1] == cell and cells[0] == (50, 50)
    assert len(set(cells)) == len(cells)  # no loops
    assert set(cells) <= walked
    for a, b in itertools.pairwise(cells):
        assert max(abs(a[0] - b[0]), abs(a[1] - b[1])) == 1


def test_a_short_track_gives_no_way_out():
    m = box_map()
    planner = make_planner("eds", "cpu")
    planner.plan(m.blocked, GOAL)
    track = Track()
    track.add(DEEP)
    path, _, lead = track_out(planner, m.blocked, m.occupancy, track)
    assert len(path) == 0 and len(lead) == 0


def test_a_passage_the_full_margin_closes_is_planned_with_less_clearance():
    """A wall across the map with one gap three cells wide: the user's radius of two cells
    closes it, one cell leaves its middle open. The way through keeps off every obstacle
    and the cells beside it, and the report says the clearance it kept."""
    occ = np.full((30, 30), FREE, np.uint8)
    occ[15, :] = OCCUPIED
    occ[15, 14:17] = FREE
    m = InflatedMap(occ, 2)
    route = Route(lambda backend: make_planner("eds", backend), "cpu", 4, 2)
    path, _ = route.path_from(m.blocked, m.occupancy, (3, 15), (27, 15))
    assert tuple(path[-1]) == (3, 15) and route.report.narrower_cells == 1
    assert route.report.way_out(0.1) == "narrow way: clearance 0.1 m"
    near = InflatedMap(occ, 1).blocked
    assert not any(near[tuple(c)] for c in path)
    # A gap one cell wide is no way at any clearance: NO_PATH, not a way past a wall's edge.
    occ[15, 14:17] = OCCUPIED
    occ[15, 15] = FREE
    m = InflatedMap(occ, 2)
    path, _ = Route(lambda b: make_planner("eds", b), "cpu", 4, 2).path_from(
        m.blocked, m.occupancy, (3, 15), (27, 15)
    )
    assert len(path) == 0


def deque_track(moves: list[tuple[int, int]], keep: int) -> list[tuple[int, int]]:
    """The track as the deque alone kept it (a scan of the deque for the loop check): the
    reference the set's lookup must agree with."""
    from collections import deque

    from daemon.navigation.pocket import TRACK_JUMP_CELLS

    cells: deque[tuple[int, int]] = deque(maxlen=keep)

    def append(cell):
        if cell in cells:
            while cells[-1] != cell:
                cells.pop()
            return
        cells.append(cell)

    cell = (100, 100)
    for dr, dc in [(0, 0), *moves]:
        cell = (cell[0] + dr, cell[1] + dc)
        if cells and cells[-1] == cell:
            continue
        if cells:
            last = cells[-1]
            gap = max(abs(cell[0] - last[0]), abs(cell[1] - last[1]))
            if gap > TRACK_JUMP_CELLS:
                cells.clear()
            for k in range(1, gap if gap <= TRACK_JUMP_CELLS else 1):
                t = k / gap
                append((round(last[0] + t * (cell[0] - last[0])),
                        round(last[1] + t * (cell[1] - last[1]))))  # fmt: skip
        append(cell)
    return list(cells)


@settings(max_examples=50, deadline=None)
@given(
    st.lists(
        st.tuples(st.integers(-6, 6), st.integers(-6, 6)).filter(lambda m: max(map(abs, m)) <= 1)
        | st.tuples(st.integers(-6, 6), st.integers(-6, 6)),
        min_size=1,
        max_size=200,
    ),
    st.sampled_from([3, 5, 20, 400]),
)
def test_the_tracks_cells_are_those_the_deque_alone_kept(moves, keep):
    """Loops cut, jumps restarting it, steps of a few cells filled in, and the oldest cells
    dropped past ``keep``: the set beside the deque changes none of it."""
    track, cell = Track(keep), (100, 100)
    track.add(cell)
    for dr, dc in moves:
        cell = (cell[0] + dr, cell[1] + dc)
        track.add(cell)
    assert list(track.cells) == deque_track(moves, keep)
    assert track._on == set(track.cells)


def test_steps_beside_a_remembered_dead_end_build_no_whole_map_and_keep_their_paths():
    """The planner holds a dead end once planned: a plain step reads only the user's cell of
    it, so no step after the plan builds the map with the dead end in it (a whole-map array:
    fresh pages at 400²), and every path is the one planned on that map."""
    import tracemalloc

    n = 300
    m = InflatedMap(np.full((n, n), FREE, np.uint8), RADIUS)
    band = np.zeros((n, n), bool)
    band[60:240, 150] = True  # a remembered dead end across the user's way
    route, ref = new_route(), new_route()
    route.dead = band.copy()
    goal = (150, 290)
    tracemalloc.start()
    try:
        for i, col in enumerate(range(10, 100, 10)):
            if i == 4:  # an obstacle seen: handed to the planner with the step's path
                wall = np.array([r * n + 200 for r in range(140, 160)])
                flipped, now = m.apply(wall, np.full(wall.size, OCCUPIED, np.uint8))
                route.change(flipped, now)
                ref.change(flipped, now | band.reshape(-1)[flipped])
            tracemalloc.reset_peak()
            before = tracemalloc.get_traced_memory()[0]
            path, cost = route.path_from(m.blocked, m.occupancy, goal, (150, col))
            peak = tracemalloc.get_traced_memory()[1] - before
            want, want_cost = ref.path_from(m.blocked | band, m.occupancy, goal, (150, col))
            assert np.array_equal(path, want) and cost == want_cost and len(path)
            assert not any(band[tuple(c)] for c in path)
            if i and i != 4:  # after the plan; the repair's own arrays are the planner's
                assert peak < band.nbytes, f"step {i}: {peak} bytes"
    finally:
        tracemalloc.stop()
    assert route.dead is not None
