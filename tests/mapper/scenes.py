"""Small known scenes for the mapper's tests, rendered by the simulated camera."""

from __future__ import annotations

import math

import numpy as np

from mapper.occupancy_mapper import MapperSettings, OccupancyMapper
from sim.camera import RgbdCamera
from sim.scene3d import BOX, PERSON, Scene3D, empty_scene

SHAPE = (60, 60)
CELL = 0.1
CAM_XY = (3.05, 1.05)
"""The camera stands in cell (49, 30), looking north."""
NORTH = math.pi / 2


def box_scene() -> Scene3D:
    """A 0.6 m cube whose near face is 1.05 m north of the camera: rows 33..38, cols 28..33."""
    scene = empty_scene(SHAPE, CELL)
    scene.put((slice(33, 39), slice(28, 34)), BOX, 0.0, 0.6)
    return scene


def person_scene(col: int) -> Scene3D:
    scene = empty_scene(SHAPE, CELL)
    scene.put((slice(35, 38), slice(col, col + 3)), PERSON, 0.0, 1.75)
    return scene


def mapper(**kw) -> OccupancyMapper:
    return OccupancyMapper(MapperSettings(shape=SHAPE, cell_m=CELL, backend="cpu", **kw))


def camera(**kw) -> RgbdCamera:
    return RgbdCamera(**kw)


def frame(scene: Scene3D, stamp: float, *, rng: int | None = None, heading: float = NORTH,
          xy: tuple[float, float] = CAM_XY, pitch: float | None = None,
          reported_pitch: float | None = None):  # fmt: skip
    cam = camera()
    true = cam.pose(xy[0], xy[1], heading, pitch)
    told = cam.pose(xy[0], xy[1], heading, reported_pitch) if reported_pitch is not None else None
    noise = np.random.default_rng(rng) if rng is not None else None
    return cam.render(scene, true, stamp, noise, reported_pose=told)
