"""Seed 004's Tables III-VI on rendered images: view widening, stitching, bird's-eye time.

Rettkowski et al. turn a Kinect on a robot (61.5° across, 640x480) and take five images;
the stitched view spans 110° (Table III, 1.8x). Stitching all five at once with SURF took
24.5 s on the Zynq's ARM and failed 40 % of 20 tries; pairwise, 27 s and 20 % (Tables IV,
V). The bird's-eye transformation of one frame took 0.245 s (Table VI). Here: the simulated
RGB-D camera, 61.5° across at 640x480, 0.45 m up and pitched 20° down, in a seeded room
(textured floor and walls, purple boxes, a green target), turning 12° between images, so five
images cover 61.5 + 4 x 12 = 109.5°; each of ``trials`` rooms is one measurement.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass

import numpy as np

from mapper.birdseye.stitch import stitch_all, stitch_pairwise
from mapper.birdseye.view import BirdsEye
from mapper.camera_model import Intrinsics

from .camera import RgbdCamera
from .scene3d import BOX, TARGET, WALL, Scene3D, empty_scene

KINECT = Intrinsics.from_fov(640, 480, 61.5)
HEIGHT_M, PITCH_DEG, TURN_DEG = 0.45, 20.0, 12.0


def room(seed: int) -> Scene3D:
    """An 8 m room: walls, three to five purple boxes, a green target mark on the floor."""
    rng = np.random.default_rng([seed, 4])
    scene = empty_scene((80, 80), 0.1)
    scene.put((slice(0, 80), slice(0, 2)), WALL, 0.0, 2.5)
    scene.put((slice(0, 80), slice(78, 80)), WALL, 0.0, 2.5)
    scene.put((slice(0, 2), slice(0, 80)), WALL, 0.0, 2.5)
    scene.put((slice(78, 80), slice(0, 80)), WALL, 0.0, 2.5)
    for _ in range(int(rng.integers(3, 6))):
        r, c = int(rng.integers(10, 55)), int(rng.integers(15, 65))
        scene.put((slice(r, r + 4), slice(c, c + 4)), BOX, 0.0, float(rng.uniform(0.3, 0.8)))
    r, c = int(rng.integers(45, 55)), int(rng.integers(25, 55))
    scene.mark[r : r + 3, c : c + 3] = TARGET
    return scene


@dataclass
class Trial:
    all_ok: bool
    all_s: float
    pair_ok: bool
    pair_s: float
    span_deg: float | None
    """The view the pairwise panorama spans (its width over the focal length)."""
    bev_ms: list[float]
    target_seen: bool


def turning_images(scene: Scene3D, seed: int, n: int = 5) -> list[np.ndarray]:
    rng = np.random.default_rng([seed, 5])
    cam = RgbdCamera(KINECT, mount_height_m=HEIGHT_M, pitch_deg=PITCH_DEG, missing=0.0)
    x, y = 4.0 + rng.uniform(-0.2, 0.2), 1.0 + rng.uniform(-0.2, 0.2)
    first = math.pi / 2 + math.radians(TURN_DEG) * (n - 1) / 2  # turning clockwise
    out = []
    for i in range(n):
        heading = first - math.radians(TURN_DEG) * i + rng.normal(0, 0.01)
        out.append(cam.render(scene, cam.pose(x, y, heading), 1.0 + i).color)
    return out


def trial(seed: int) -> Trial:
    scene = room(seed)
    images = turning_images(scene, seed)
    a = stitch_all(images)
    p = stitch_pairwise(images)
    span = None
    if p.image is not None:
        span = math.degrees(p.image.shape[1] / KINECT.fx)
    bev = BirdsEye(KINECT, HEIGHT_M, math.radians(PITCH_DEG))
    ms, seen = [], False
    for img in images:
        t0 = time.perf_counter()
        _, target = bev(img)
        ms.append((time.perf_counter() - t0) * 1e3)
        seen |= bev.target_xy(target) is not None
    return Trial(a.image is not None, a.seconds, p.status == "ok", p.seconds, span, ms, seen)


PAPER = {
    "view": (61.5, 110.0, 1.8),
    "stitch_s": (24.5, 27.0),
    "failure": (0.40, 0.20),
    "bev_s": 0.245,
}
