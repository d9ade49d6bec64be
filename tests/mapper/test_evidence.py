"""Evidence fused over frames: one frame cannot close a passage seen free, a face's
range-noise tail is no obstacle, and STOP still comes from the latest frame alone."""

from __future__ import annotations

import numpy as np

from mapper.binning import Window
from mapper.evidence import range_tail
from mapper.occupancy_mapper import FREE, OCCUPIED
from sim.scene3d import empty_scene

from .scenes import CELL, SHAPE, frame, mapper, person_scene


def _window() -> Window:
    # A 9 x 9 window whose centre cell (4, 4) holds the camera; map rows = 9.
    return Window(0, 0, 9, 9, 1.0)


def test_a_face_tail_in_front_of_it_is_no_hit_but_a_real_neighbour_is():
    win = _window()
    cam_x, cam_y = 4.5, 4.5  # centre of cell (4, 4); north is row - 1
    obst = np.zeros((9, 9), np.int32)
    obst[1, 4] = 100  # a face three cells north of the camera
    obst[2, 4] = 20  # its range-noise tail, one cell nearer: a fifth of the face
    obst[1, 3] = 100  # the face goes on west ...
    obst[2, 3] = 40  # ... and there the nearer cell holds a second thing of its own
    obst[0, 4] = 5  # the top behind the face: fewer points, but beyond, not in front
    tail = range_tail(obst, win, cam_x, cam_y, 0.25)
    assert tail[2, 4]
    assert not tail[2, 3]
    assert not tail[1, 4] and not tail[1, 3] and not tail[0, 4]
    assert not tail[obst == 0].any()


def test_one_frame_does_not_close_a_passage_seen_free_but_stop_still_comes():
    m = mapper()
    cells = (37, slice(29, 32))
    for i in range(5):  # the floor where the person will stand is seen free, frame on frame
        m.process(frame(empty_scene(SHAPE, CELL), 1.0 + 0.1 * i, rng=i))
    assert (m.occupancy[cells] == FREE).all()
    # One frame shows something there (a glitch, or someone stepping in).
    r = m.process(frame(person_scene(29), 1.5, rng=9))
    assert (m.occupancy[cells] == FREE).all()  # the map waits for more evidence ...
    assert r.proximity.ahead_m is not None and r.proximity.ahead_m < 1.4  # ... STOP does not
    # Someone who stays is mapped once the hits outweigh what was seen free: 4 frames.
    n = 1
    while not (m.occupancy[cells] == OCCUPIED).all():
        m.process(frame(person_scene(29), 1.6 + 0.1 * n, rng=10 + n))
        n += 1
        assert n <= 4
    assert n == 4
