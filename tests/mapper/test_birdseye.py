"""Seed 004's camera map: the homography, the HSV maps, the target, stitching."""

from __future__ import annotations

import math

import cv2
import numpy as np

from mapper.birdseye.stitch import stitch_pairwise
from mapper.birdseye.view import BEV_SIZE, BirdsEye
from sim.birdseye_study import HEIGHT_M, KINECT, PITCH_DEG, room, turning_images
from sim.camera import RgbdCamera
from sim.scene3d import BOX, TARGET, empty_scene


def bev() -> BirdsEye:
    return BirdsEye(KINECT, HEIGHT_M, math.radians(PITCH_DEG))


def test_the_trapezoid_goes_to_the_whole_320x340_rectangle():
    b = bev()
    corners = b.patch.trapezoid(KINECT, HEIGHT_M, math.radians(PITCH_DEG))
    mapped = cv2.perspectiveTransform(corners[None], b.homography)[0]
    w, h = BEV_SIZE
    assert np.allclose(mapped, [(0, 0), (w - 1, 0), (w - 1, h - 1), (0, h - 1)], atol=1e-3)
    far_l, far_r, near_r, near_l = corners  # a trapezoid: the far edge is the narrower
    assert (far_r[0] - far_l[0]) < (near_r[0] - near_l[0])


def test_target_and_box_found_where_they_are():
    scene = empty_scene((60, 60), 0.1)
    # Camera at (3.0, 1.0) facing north: the target 2 m ahead, 0.3 m to the left.
    scene.mark[28:31, 26:29] = TARGET  # centre x = 2.75, y = 3.0 (rows 28..30 → y 2.9..3.2)
    scene.put((slice(33, 36), slice(31, 34)), BOX, 0.0, 0.3)  # 1.4 m ahead, to the right
    cam = RgbdCamera(KINECT, mount_height_m=HEIGHT_M, pitch_deg=PITCH_DEG, missing=0.0)
    img = cam.render(scene, cam.pose(3.0, 1.0, math.pi / 2), 1.0).color
    b = bev()
    obstacles, target = b(img)
    assert obstacles.shape == (BEV_SIZE[1], BEV_SIZE[0]) and set(np.unique(obstacles)) <= {0, 1}
    fwd, left = b.target_xy(target)
    assert abs(fwd - 2.05) < 0.15 and abs(left - 0.25) < 0.15
    cells = b.cells(obstacles, 3.0, 1.0, math.pi / 2, (60, 60), 0.1)
    rows, cols = np.divmod(cells, 60)
    # The near edge is where the box stands; a bird's-eye view takes everything for floor,
    # so the box's face and top smear away from the camera (seed 004's view does the same).
    assert cells.size > 0 and 34 <= rows.max() <= 36
    assert cols.min() >= 30 and cols.max() <= 36  # the smear is radial: outward too


def test_no_target_in_view_says_so():
    img = (
        RgbdCamera(KINECT, mount_height_m=HEIGHT_M, pitch_deg=PITCH_DEG)
        .render(
            empty_scene((60, 60), 0.1), RgbdCamera().pose(3.0, 1.0, math.pi / 2, PITCH_DEG), 1.0
        )
        .color
    )
    _, target = bev()(img)
    assert bev().target_xy(target) is None


def test_five_images_taken_while_turning_stitch_wider_than_one():
    images = turning_images(room(3), 3)
    result = stitch_pairwise(images)
    assert result.status == "ok" and result.image is not None
    assert result.image.shape[1] > 1.4 * images[0].shape[1]
