"""Free space along the rays: a person who walks away leaves no ghost; forgetting."""

from __future__ import annotations

from mapper.occupancy_mapper import FREE, OCCUPIED
from sim.scene3d import empty_scene

from .scenes import NORTH, box_scene, frame, mapper, person_scene


def test_person_who_walks_away_is_cleared():
    m = mapper()
    m.process(frame(person_scene(29), 1.0))
    assert (m.occupancy[37, 29:32] == OCCUPIED).all()
    # They step two cells to the side; the next frame sees the floor where they stood.
    result = m.process(frame(person_scene(35), 1.2))
    assert (m.occupancy[37, 29:32] == FREE).all()
    assert (m.occupancy[37, 35:38] == OCCUPIED).all()
    changed = set(result.cells.tolist())
    assert {37 * 60 + c for c in range(29, 32)} <= changed  # the clearing went out as a delta


def test_unseen_obstacle_is_forgotten_but_the_start_map_is_not():
    import numpy as np

    start = np.full((60, 60), 2, np.uint8)
    start[0, :] = OCCUPIED  # a known wall, far behind the camera's view
    m = mapper(forget_s=5.0, forget_static_s=20.0)
    m.occupancy[...] = start
    m._fixed = start == OCCUPIED
    m.process(frame(box_scene(), 0.0))  # a box first seen as a box: a static face
    m.process(frame(empty_scene((60, 60), 0.1), 1.0, xy=(1.05, 1.05)))  # the floor, free
    m.process(frame(person_scene(9), 1.5, xy=(1.05, 1.05)))  # a person walks in there
    assert (m.occupancy[37, 9:12] == OCCUPIED).all() and m.mover[37, 9:12].all()
    assert (m.occupancy[38, 28:34] == OCCUPIED).all() and not m.mover[38, 28:34].any()
    # The camera turns away (south) and keeps looking there for 6 s.
    for i in range(7):
        m.process(frame(person_scene(9), 2.0 + i, heading=-NORTH, xy=(1.05, 1.05)))
    assert (m.occupancy[37, 9:12] == 2).all()  # the person: gone back to unknown
    assert (m.occupancy[38, 28:34] == OCCUPIED).all()  # the box: not yet
    # A dead end the user walked away from stays one for a while, then is looked at again.
    for i in range(15):
        m.process(frame(person_scene(9), 10.0 + i, heading=-NORTH, xy=(1.05, 1.05)))
    assert (m.occupancy[38, 28:34] == 2).all()
    assert (m.occupancy[0, :] == OCCUPIED).all()
