"""Small known scenes for the mapper's tests, rendered by the simulated camera."""

from __future__ import annotations

import dataclasses
import math

import numpy as np

from mapper.camera_model import CameraPose
from mapper.frame import FrameLimits, FrameRejected, Refusal
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


def bad_frames(good):
    """Frames each refused for one reason, made from ``good``, with that reason."""
    nan = good.depth.astype(np.float32) / 1000.0
    nan[:] = np.nan
    far = CameraPose.level(8.0, 5.0, 1.3, 1.57, 0.5)
    return [
        (dataclasses.replace(good, depth=good.depth[:, :-1]), Refusal.WRONG_SIZE),
        (dataclasses.replace(good, intrinsics=None), Refusal.NO_INTRINSICS),
        (dataclasses.replace(good, pose=None), Refusal.NO_POSE),
        (dataclasses.replace(good, depth=np.zeros_like(good.depth)), Refusal.NO_DEPTH),
        (dataclasses.replace(good, depth=nan), Refusal.NO_DEPTH),
        (dataclasses.replace(good, depth=good.depth.astype(np.int32)), Refusal.BAD_DEPTH),
        (dataclasses.replace(good, stamp=9.0), Refusal.STALE),
        (dataclasses.replace(good, stamp=10.0), Refusal.STALE),
        (dataclasses.replace(good, stamp=float("nan")), Refusal.STALE),
        (dataclasses.replace(good, pose=far, stamp=10.1), Refusal.POSE_JUMP),
    ]


def edge_frames(good):
    """What ``bad_frames`` lacks: the share of pixels at the limit and one pixel under it,
    float depth with every kind of missing pixel, and no depth together with a jump."""
    need = math.ceil(FrameLimits().min_valid_share * good.depth.size)
    at, under = np.zeros_like(good.depth), np.zeros_like(good.depth)
    at.flat[-need:], under.flat[-need + 1 :] = 1500, 1500
    holes = good.depth.astype(np.float32) / 1000.0
    holes.flat[::3], holes.flat[1::7], holes.flat[2::11] = np.nan, np.inf, -1.0
    far = CameraPose.level(8.0, 5.0, 1.3, 1.57, 0.5)
    return [
        dataclasses.replace(good, depth=under),
        dataclasses.replace(good, depth=np.zeros_like(good.depth), pose=far),
        dataclasses.replace(good, depth=at),
        dataclasses.replace(good, depth=holes),
    ]


def outcome(m: OccupancyMapper, f) -> object:
    """What ``m`` made of ``f``: "mapped", or the refusal and its reason; then the floor fit
    the frame left due, run and waited for (``floor_async``), as the node does."""
    try:
        m.process(f)
        said: object = "mapped"
    except FrameRejected as exc:
        said = (exc.refusal, exc.reason)
    m.fit_pending_floor()
    m.wait_for_floor()
    return said
