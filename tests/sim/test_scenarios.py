"""The scenarios beside the courtyard: seeded, connected, honest about what is known."""

from __future__ import annotations

import numpy as np
import pytest

from daemon.planning.dijkstra import dijkstra_field
from daemon.planning.grid import FREE, INF, OCCUPIED, UNKNOWN
from sim.building import building_doors, make_building
from sim.courtyard import connected, dilate, make_courtyard
from sim.scenarios import SCENARIOS, make_scenario, scenario_list
from sim.walk import walk

pytestmark = pytest.mark.timeout(120)

PROCEDURAL = ("building", "streets")


@pytest.mark.parametrize("name", SCENARIOS)
def test_same_seed_same_scenario_other_seed_another(name):
    a = make_scenario(name, 100, 0.4, seed=0)
    b = make_scenario(name, 100, 0.4, seed=0)
    c = make_scenario(name, 100, 0.4, seed=1)
    assert a.name == name
    assert np.array_equal(a.true, b.true) and np.array_equal(a.known, b.known)
    assert (a.start, a.goal) == (b.start, b.goal)
    assert not np.array_equal(a.true, c.true)
    if name in PROCEDURAL:  # another layout, not only other blobs
        assert not np.array_equal(a.known, c.known)


@pytest.mark.parametrize("name", SCENARIOS)
@pytest.mark.parametrize("grid", [100, 200])
@pytest.mark.parametrize("unknown", [0.0, 0.4])
def test_known_is_a_subset_of_true_and_the_ends_connect(name, grid, unknown):
    s = make_scenario(name, grid, unknown, seed=0)
    assert s.known.dtype == np.uint8 and s.true.dtype == np.uint8
    assert s.known.flags.c_contiguous and s.true.flags.c_contiguous
    assert set(np.unique(s.known)) <= {OCCUPIED, UNKNOWN}
    assert set(np.unique(s.true)) <= {FREE, OCCUPIED}
    assert np.all(s.true[s.known == OCCUPIED] == OCCUPIED)
    blocked = dilate(s.true == OCCUPIED, s.radius_cells)
    assert not blocked[s.start] and not blocked[s.goal]
    assert connected(blocked, s.start, s.goal)
    if grid == 100:  # the reference Dijkstra is pure Python
        assert dijkstra_field(blocked, s.goal)[s.start] < INF
    assert abs(s.coverage - unknown) < 0.03


@pytest.mark.parametrize("name", PROCEDURAL)
@pytest.mark.parametrize("grid", [100, 133, 150, 257])
def test_any_grid_side_is_the_same_layout_in_metres(name, grid):
    s = make_scenario(name, grid, 0.2, seed=0)
    extent = 20.0 if name == "building" else 40.0
    assert s.shape == (grid, grid)
    assert s.cell_m == pytest.approx(extent / grid)
    assert s.sensor_range_cells == pytest.approx(3.0 / s.cell_m)
    assert s.radius_cells == int(np.ceil(0.3 / s.cell_m - 1e-9))
    # start and goal at the same place in metres whatever the grid, far apart
    ref = make_scenario(name, 200, 0.2, seed=0)
    for cell, ref_cell in ((s.start, ref.start), (s.goal, ref.goal)):
        assert np.allclose(np.multiply(cell, s.cell_m), np.multiply(ref_cell, ref.cell_m),
                           atol=2 * s.cell_m)  # fmt: skip
    apart = np.hypot(*np.subtract(s.start, s.goal)) * s.cell_m
    assert apart > 0.45 * extent
    assert s.start[0] > s.goal[0] and s.start[1] < s.goal[1]  # south-west to north-east
    # the same layout at every grid: finer than its 200 base cells, the same share of it
    # known; coarser, walls straddling a cell thicken but never thin away
    known_fraction, ref_fraction = np.mean(s.known == OCCUPIED), np.mean(ref.known == OCCUPIED)
    if grid >= 200:
        assert known_fraction == pytest.approx(ref_fraction, abs=0.005)
    else:
        assert ref_fraction - 0.005 <= known_fraction <= 2 * ref_fraction


def test_explore_knows_nothing_of_the_courtyard_it_walks():
    s = make_scenario("explore", 100, 0.4, seed=3)
    c = make_courtyard(100, 0.4, seed=3)
    assert np.all(s.known == UNKNOWN)
    assert np.array_equal(s.true, c.true) and (s.start, s.goal) == (c.start, c.goal)
    assert np.all(s.true[0] == OCCUPIED)  # the walls are there, only not known


def test_building_closes_doors_of_the_plan_and_one_on_its_route():
    s = make_building(100, 0.0, seed=0)
    doors, closed = building_doors(seed=0)
    assert len(doors) >= 15 and 2 <= len(closed) < len(doors)
    # the known plan (every door open) has a shorter way than the true world: a door on
    # the planned route is shut, so the walk must re-route
    known = dijkstra_field(dilate(s.known == OCCUPIED, s.radius_cells), s.goal)[s.start]
    true = dijkstra_field(dilate(s.true == OCCUPIED, s.radius_cells), s.goal)[s.start]
    assert known < true < INF
    # closed doors are walls of the true world that the known map has open
    shut = (s.true == OCCUPIED) & (s.known != OCCUPIED)
    assert shut.sum() > 0


def test_building_walk_replans_round_a_closed_door():
    s = make_building(100, 0.0, seed=0)
    result = walk(s, backend="cpu", mode="eds")
    assert result.arrived
    # cells turned blocked on the way: the closed doors the sensor saw
    assert result.changed.sum() > 0
    blocked = dilate(s.known == OCCUPIED, s.radius_cells)
    best_known = dijkstra_field(blocked, s.goal)[s.start] / 10.0 * s.cell_m
    assert result.walked_m > best_known + 0.5


@pytest.mark.parametrize(
    ("name", "grid"),
    [("courtyard", 100), ("explore", 100), ("building", 100), ("building", 150),
     ("streets", 100), ("streets", 150)],
)  # fmt: skip
def test_eds_arrives_and_dss_walks_the_same_cells(name, grid):
    s = make_scenario(name, grid, 0.4, seed=0)
    eds = walk(s, backend="cpu", mode="eds")
    dss = walk(s, backend="cpu", mode="dss")
    assert eds.arrived and dss.arrived
    assert tuple(eds.walked[-1]) == s.goal
    assert np.array_equal(eds.walked, dss.walked)
    assert not np.any(s.true[eds.walked[:, 0], eds.walked[:, 1]] == OCCUPIED)


def test_bad_names_sizes_and_fractions_are_refused_clearly():
    with pytest.raises(ValueError, match=r"unknown scenario 'mall'.*courtyard"):
        make_scenario("mall", 100, 0.4, 0)
    with pytest.raises(ValueError, match="unknown scenario 'mall'"):
        scenario_list("courtyard,mall")
    with pytest.raises(ValueError, match="no scenario"):
        scenario_list(" , ")
    assert scenario_list("building, streets") == ["building", "streets"]
    for name in PROCEDURAL:
        with pytest.raises(ValueError, match=f"{name}: grid must be at least"):
            make_scenario(name, 40, 0.4, 0)
        with pytest.raises(ValueError, match="unknown must be in"):
            make_scenario(name, 100, 1.0, 0)
    with pytest.raises(ValueError, match="multiple or a divisor"):
        make_scenario("explore", 150, 0.4, 0)
