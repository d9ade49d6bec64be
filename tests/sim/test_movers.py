"""Hong & DeSouza's room crossing with wandering people: seeded, no ghost obstacles, and the
default planner (EDS) crosses without walking into anyone (a couple of trials; the 100-trial
figures come from ``guidebelt walks --movers``)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from daemon.planning.grid import FREE, OCCUPIED
from sim.movers import CLEAR_M, Movers, crossing_trial, room_scenario
from sim.world import World

pytestmark = pytest.mark.timeout(120)


class Standing:
    """A walker that stands and looks round: the sensor sweeps the room."""

    def __init__(self, x: float, y: float) -> None:
        self.x, self.y, self.heading = x, y, 0.0

    def act(self, view) -> str:
        self.heading += math.radians(40)
        return "turn"


def test_people_move_at_walking_speed_and_keep_clear_of_the_walker():
    scenario = room_scenario()
    crowd = Movers(scenario.true, 10, seed=3)
    world = World(scenario, Standing(3.0, 3.0))
    before = [(p.x, p.y) for p in crowd.people]
    crowd(world, 0.6)
    for (x0, y0), p in zip(before, crowd.people, strict=True):
        assert math.hypot(p.x - x0, p.y - y0) <= 1.4 * 0.6 + 1e-9
        assert math.hypot(p.x - 3.0, p.y - 3.0) >= CLEAR_M or (x0, y0) == (p.x, p.y)
    assert (world.true == OCCUPIED).sum() > (scenario.true == OCCUPIED).sum() - 1
    again = Movers(room_scenario().true, 10, seed=3)
    assert [(p.x, p.y) for p in again.people] == before


def test_a_cell_a_person_left_is_free_again_once_the_sensor_sees_it():
    scenario = room_scenario()
    crowd = Movers(scenario.true, 3, seed=1)
    world = World(scenario, Standing(3.0, 3.0), fov_deg=360.0)
    crowd(world, 0.0)
    world.sense(0.0)
    ever = world.known == OCCUPIED
    for k in range(1, 8):
        crowd(world, 0.6 * k)
        world.sense(0.6 * k)  # a full sweep: everything in range is looked at every tick
        inside = np.zeros_like(ever)
        inside[1:-1, 1:-1] = True
        seen_range = world.sensor.visible(world.shape, world.cell(), 0.0)
        known, true = world.known.reshape(-1), world.true.reshape(-1)
        assert (known[seen_range] == true[seen_range]).all()
        ever |= world.known == OCCUPIED
    # People walked: cells they covered once are FREE now where the sensor looked.
    assert ((ever & (world.known == FREE))[inside]).any()


@pytest.mark.parametrize("planner", ["eds", "harmonic"])
def test_crossings_with_ten_people(planner):
    for seed in range(2):
        t = crossing_trial(planner, 10, seed)
        assert t.collisions == 0
        if planner == "eds":
            assert t.success and t.time_s > 0 and t.walked_m > 1.5  # 2.2 m less the arrival radius
