"""Free space along the rays: a person who walks away leaves no ghost; forgetting."""

from __future__ import annotations

import math

from mapper.occupancy_mapper import FREE, OCCUPIED

from .scenes import frame, mapper, person_scene


def test_person_who_walks_away_is_cleared():
    m = mapper()
    s = m.settings
    m.process(frame(person_scene(29), 1.0))
    assert (m.occupancy[37, 29:32] == OCCUPIED).all()  # one frame maps a new obstacle
    for i in range(10):  # they stand long enough for the evidence to saturate
        m.process(frame(person_scene(29), 1.1 + 0.1 * i, rng=i))
    assert (m.logodds[37, 29:32] == s.l_max).all()
    # They step to the side; each frame's rays pass where they stood, over its floor.
    bound = math.ceil((s.l_max - s.l_free) / -s.l_pass)
    assert bound == 10
    for n in range(1, bound + 1):
        result = m.process(frame(person_scene(35), 2.1 + 0.1 * n, rng=100 + n))
        if (m.occupancy[37, 29:32] == FREE).all():
            break
    assert (m.occupancy[37, 29:32] == FREE).all(), "a ghost outlived the bound"
    assert n == bound  # no frame earlier: one frame's passes do not wipe a known obstacle
    assert (m.occupancy[37, 35:38] == OCCUPIED).all()
    changed = set(result.cells.tolist())
    assert {37 * 60 + c for c in range(29, 32)} <= changed  # the clearing went out as a delta


def test_unseen_obstacle_is_forgotten_but_the_start_map_is_not():
    import numpy as np

    start = np.full((60, 60), 2, np.uint8)
    start[0, :] = OCCUPIED  # a known wall, far behind the camera's view
    m = mapper(forget_s=5.0)
    m.occupancy[...] = start
    m._fixed = start == OCCUPIED
    m.process(frame(person_scene(29), 1.0))
    assert (m.occupancy[37, 29:32] == OCCUPIED).all()
    # The camera turns away (east) and keeps looking there for 6 s.
    for i in range(7):
        m.process(frame(person_scene(29), 2.0 + i, heading=0.0))
    assert (m.occupancy[37, 29:32] == 2).all()  # gone back to unknown
    assert (m.occupancy[0, :] == OCCUPIED).all()
