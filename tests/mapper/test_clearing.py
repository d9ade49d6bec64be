"""Free space along the rays: a person who walks away leaves no ghost; forgetting."""

from __future__ import annotations

from mapper.occupancy_mapper import FREE, OCCUPIED

from .scenes import frame, mapper, person_scene


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
