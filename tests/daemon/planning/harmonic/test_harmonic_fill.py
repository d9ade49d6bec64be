"""A replanning step's bounded repair (``fill.py``): after every step every reachable cell has
a strictly lower neighbour, whatever the sweeps left, and ``converge`` still reaches the
harmonic field. The fill is forced here by a step of one sweep (``step_cap`` 1)."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from daemon.planning import make_planner
from daemon.planning.harmonic import fill as fl
from daemon.planning.harmonic import relax as rx
from daemon.planning.harmonic.cpu import CpuField
from daemon.planning.harmonic.planner import TOL

pytestmark = pytest.mark.timeout(120)

FIELD_TOL = 5e-3
"""As ``test_harmonic_planner``: two relaxations of one map to 1e-4 agree within this."""


def one_sweep_steps(variant: str = "fast"):
    planner = make_planner("harmonic", "cpu", variant)
    planner.step_sweeps, planner.step_cap = 1, 1
    return planner


@settings(
    max_examples=25, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture]
)
@given(seed=st.integers(0, 2**31), h=st.integers(3, 24), w=st.integers(3, 24),
       density=st.floats(0.0, 0.45), variant=st.sampled_from(["fast", "paper"]))  # fmt: skip
def test_every_step_is_pit_free_and_converge_equals_a_cold_plan(maps, seed, h, w, density, variant):
    rng = np.random.default_rng(seed)
    blocked = maps.random_map(rng, h, w, density)
    goal = (int(rng.integers(0, h)), int(rng.integers(0, w)))
    blocked[goal] = False
    planner = one_sweep_steps(variant)
    planner.plan(blocked, goal)
    for _ in range(4):
        cells = rng.integers(0, h * w, size=int(rng.integers(1, 12)))
        values = rng.random(cells.size) < 0.6
        values[cells == goal[0] * w + goal[1]] = False
        stats = planner.update(cells, values)
        blocked.reshape(-1)[cells] = values
        assert stats.iterations <= 1  # bounded: one sweep, then the fill
        assert planner.settled
        engine = planner.engine
        assert not rx.has_pit(engine.w, engine.fixed, engine.width)
        if stats.iterations:  # a step ran (a change the goal feels): its fill's Idx is the
            # field's own (the GPU's host walks its copy of it)
            fresh, pits = np.empty_like(engine.idx), np.empty(engine.idx.size, np.int64)
            assert fl.lowest_each(engine.w, engine.fixed, engine.width, fresh, pits) == 0
            assert (fresh == engine.idx).all()
        maps.descents_hold(planner, blocked, maps.reachable(blocked, goal))
    assert planner.retries == 0  # no descent needed the tighter relaxation
    planner.converge()
    assert planner.residual < TOL or planner.reach.count == 0
    cold = make_planner("harmonic", "cpu", variant)
    cold.plan(blocked, goal)
    reach = maps.reachable(blocked, goal) & ~blocked
    assert np.abs(planner.field()[reach] - cold.field()[reach]).max(initial=0.0) < FIELD_TOL


def drained_room():
    """A room whose field drains through a door on the right of a wall, and the change that
    closes that door: everything below the wall must now spill through the door on the left."""
    blocked = np.zeros((40, 40), dtype=bool)
    blocked[20, :] = True
    blocked[20, 2:4] = blocked[20, 34:38] = False  # the doors: left far, right near the path
    door = 20 * 40 + np.arange(34, 38)
    return blocked, (2, 36), door


def test_a_wall_across_the_drained_basin_is_filled_within_the_step(maps):
    blocked, goal, door = drained_room()
    planner = make_planner("harmonic", "cpu")
    planner.plan(blocked, goal)
    # Close the door with few sweeps allowed: the basin below cannot spill the other way by
    # relaxation (hundreds of sweeps), so the step fills it.
    planner.step_sweeps, planner.step_cap = 5, 5
    stats = planner.update(door, True)
    blocked.reshape(-1)[door] = True
    assert stats.iterations <= 5
    assert planner.filled > 100 and planner.settled  # the room below the wall
    maps.descents_hold(planner, blocked, maps.reachable(blocked, goal))
    path = planner.path((35, 36))
    assert {(20, 2), (20, 3)} & {tuple(p) for p in path}  # out through the far door


def test_the_flood_only_raises_the_basins_and_leaves_the_rest():
    # A sloped open field (the goal at a corner) with a bowl sunk into it.
    n = 60
    r, c = np.mgrid[0 : n + 2, 0 : n + 2]
    w = 0.05 * np.hypot(r - 2, c - 2)
    bowl = np.hypot(r - 40, c - 40) < 8
    w[bowl] = w[40, 40] - 3.0 + 0.01 * np.hypot(r - 40, c - 40)[bowl]
    blocked = np.ones((n + 2, n + 2), dtype=bool)
    blocked[1:-1, 1:-1] = False
    w[blocked] = rx.BLOCKED_W
    goal = 2 * (n + 2) + 2
    w.reshape(-1)[goal] = 0.0
    fixed = blocked.reshape(-1).copy()
    fixed[goal] = True
    engine = CpuField()
    engine.load(fixed, w.reshape(-1), n + 2, goal)
    assert rx.has_pit(engine.w, fixed, n + 2)
    n_basin, left = engine.fill()
    assert left == 0 and n_basin >= bowl.sum()
    assert not rx.has_pit(engine.w, fixed, n + 2)
    after = engine.w.reshape(n + 2, n + 2)
    assert (after >= w).all()
    # Only the basins rose (the bowl and the slope behind it that drains in); the slope
    # between the bowl and the goal is kept as it was.
    assert (after != w).sum() <= n_basin
    assert (after[np.hypot(r - 2, c - 2) < 25] == w[np.hypot(r - 2, c - 2) < 25]).all()
    # Filled to the rim's level, not above it by more than ε a cell across the bowl.
    rim = w[np.hypot(r - 40, c - 40) < 9].max()
    assert after[bowl].max() <= rim + 20 * fl.EPS
    assert engine.descend(40 * (n + 2) + 40)[-1] == goal
    # The Idx the fill wrote for the basins is the field's own (the GPU's host walks it).
    written, fresh = engine.idx.copy(), np.empty_like(engine.idx)
    assert fl.lowest_each(engine.w, fixed, n + 2, fresh, np.empty(fresh.size, np.int64)) == 0
    assert (written == fresh).all()


def test_a_float32_fill_stays_strictly_above_where_eps_is_below_rounding():
    # w ~ 3e4: float32's spacing there (0.002) is larger than ε, so v + ε rounds back to v.
    w = np.full((5, 7), 3.0e4, dtype=np.float32)
    w[0, :] = w[-1, :] = w[:, 0] = w[:, -1] = rx.BLOCKED_W
    w[2, 1] = 2.9e4  # a fixed cell below the rest: the only way down
    flat = w.reshape(-1)
    fixed = flat >= rx.BLOCKED_W
    fixed[2 * 7 + 1] = True
    idx = np.empty(flat.size, dtype=np.int8)
    pits = np.empty(flat.size, dtype=np.int64)
    mark = np.zeros(flat.size, dtype=np.int8)
    cells = np.empty(flat.size, dtype=np.int64)
    count = fl.lowest_each(flat, fixed, 7, idx, pits)
    assert count > 0
    counts = fl.basins(idx, fixed, 7, pits[:count].copy(), mark, cells)
    assert fl.flood(flat, 7, cells, *counts, fl.EPS, mark, idx) == 0
    assert not rx.has_pit(flat, fixed, 7)
    assert (mark == 0).all()
    assert fl.lowest_each(flat, fixed, 7, idx.copy(), pits) == 0


@pytest.mark.parametrize("seed", range(3))
def test_the_basins_are_the_cells_whose_descent_ends_at_a_pit_in_either_list_type(seed):
    # A bumpy field (many pits, some cells with no value yet, some fixed): the basins are
    # exactly the free cells whose Idx chain, through free cells, ends at a pit. The device's
    # call (int32 pits and cells, no rings) finds the same cells and leaves ``mark`` zeroed.
    rng = np.random.default_rng(seed)
    h, width = 30, 41
    w = rng.random((h, width)) * 5.0
    w[rng.random((h, width)) < 0.05] = rx.BLOCKED_W  # free, no value yet
    w[0, :] = w[-1, :] = w[:, 0] = w[:, -1] = rx.BLOCKED_W
    flat = w.reshape(-1)
    fixed = flat >= rx.BLOCKED_W
    fixed[rng.random(flat.size) < 0.1] = True
    fixed[flat.size // 2] = False
    idx = np.empty(flat.size, dtype=np.int8)
    pits = np.empty(flat.size, dtype=np.int64)
    count = fl.lowest_each(flat, fixed, width, idx, pits)
    assert count > 10
    offs = fl._offsets(width)
    pit_set = set(pits[:count].tolist())
    expected = set()
    for i in range(flat.size):
        c = i
        while not fixed[c] and c not in pit_set and idx[c] != 4:
            c += offs[idx[c]]
        if not fixed[i] and c in pit_set:
            expected.add(i)
    mark = np.zeros(flat.size, dtype=np.int8)
    cells = np.empty(flat.size, dtype=np.int64)
    n = fl.basins(idx, fixed, width, pits[:count].copy(), mark, cells)[0]
    assert n == len(expected) and set(cells[:n].tolist()) == expected
    mark[:] = 0
    cells32 = np.empty(flat.size, dtype=np.int32)
    counts = fl.basins(idx, fixed, width, pits[:count].astype(np.int32), mark, cells32, False)
    assert counts == (n, 0, 0)
    assert set(cells32[:n].tolist()) == expected
    assert (mark == 0).all()
