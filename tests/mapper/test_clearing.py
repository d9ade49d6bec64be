"""Free space along the rays and on the floor seen: a person who walks away leaves no
ghost, also beside a near box; forgetting."""

from __future__ import annotations

import math

import numpy as np

from mapper.binning import bin_frame_cpu
from mapper.occupancy_mapper import FREE, OCCUPIED
from sim.scene3d import BOX, PERSON, empty_scene

from .scenes import CAM_XY, CELL, SHAPE, frame, mapper, person_scene


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


def _box_at_front_left(person: bool = False):
    """A 1 m box 0.5 m from the camera at its front left (45°), where the bottom rows of a
    camera pitched down 30° see it, and maybe a person 2.5 m off at 25° left."""
    scene = empty_scene(SHAPE, CELL)
    scene.put((slice(44, 46), slice(25, 27)), BOX, 0.0, 1.0)
    if person:
        scene.put((slice(25, 28), slice(18, 21)), PERSON, 0.0, 1.75)
    return scene


def _bearing(x: float, y: float) -> float:
    """Degrees left of north (the camera's heading) from the camera."""
    return math.degrees(math.atan2(y - CAM_XY[1], x - CAM_XY[0])) - 90.0


def test_a_ray_ends_at_the_nearest_obstacle_of_its_own_bearing():
    """Each bin's nearest obstacle and farthest free point lie at one bearing. Binned by
    image column they did not: the box's bottom-left pixels share columns with floor seen
    20° further right, and ended those columns' rays at the box."""
    m = mapper()
    f = frame(_box_at_front_left(), 1.0, rng=1)
    rot, t = f.pose.world_from_optical(), np.asarray(f.pose.position)
    s = m.settings
    b = bin_frame_cpu(f.depth, f.intrinsics.depth_scale, f.intrinsics, rot, t, 0.0,
                      m.window(t[0], t[1]), s.min_height_m, s.max_height_m, s.max_range_m,
                      s.cols_per_bin, s.stride)  # fmt: skip
    both = np.isfinite(b.hit[:, 0]) & (b.far[:, 0] >= 0)
    assert both.sum() >= 2  # the box's edge bins see floor beside it
    assert np.isfinite(b.hit[:, 0]).sum() >= 10
    for (_, hx, hy), (_, fx, fy) in zip(b.hit[both], b.far[both], strict=True):
        assert abs(_bearing(hx, hy) - _bearing(fx, fy)) < 2.0


def test_a_ghost_beside_a_near_box_is_cleared_and_a_person_who_stays_is_not():
    """Someone stood 2.5 m off at 25° left, then walked on; the floor where they stood is in
    plain view past the box at the front left. The map frees it within the bound of
    ``test_person_who_walks_away_is_cleared``; had they stayed, it stays an obstacle."""
    cells = (slice(25, 28), slice(18, 21))
    for stays in (False, True):
        m = mapper()
        for i in range(3):
            m.process(frame(_box_at_front_left(person=True), 1.0 + 0.1 * i, rng=i))
        face = (27, slice(18, 21))  # the side the camera sees
        assert (m.occupancy[face] == OCCUPIED).all()
        for i in range(10):
            m.process(frame(_box_at_front_left(person=stays), 2.0 + 0.1 * i, rng=10 + i))
        assert (m.occupancy[face] == OCCUPIED).all() == stays
        if not stays:
            assert (m.occupancy[cells] != OCCUPIED).all()
            assert (m.occupancy[face] == FREE).all()
        assert (m.occupancy[44:46, 25:27] == OCCUPIED).all()  # the box itself stays
