"""Bird's-eye view: a homography from the floor's trapezoid in the image to a rectangle.

Seed 004 "defines corner points of a trapezoid inside the image ... by means of these points,
the homography matrix is calculated to transform the image in a top down bird's eye view",
then converts it to HSV and thresholds it into a binary image; "the image size ... is
640x480 pixels and resized down to 320x340". Here the trapezoid is where a rectangle of floor
(``width_m`` across, from ``near_m`` to ``far_m`` ahead) falls in the image of a camera of
known intrinsics, height and pitch, so each bird's-eye pixel is a known patch of floor; the
homography itself is OpenCV's ``getPerspectiveTransform``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import cv2
import numpy as np

from ..camera_model import Intrinsics

BEV_SIZE = (320, 340)
"""(width, height) of the bird's-eye image, seed 004's 320x340."""

GREEN = ((40, 80, 80), (85, 255, 255))
"""HSV range of the target (OpenCV's hue is 0..179)."""
PURPLE = ((130, 80, 50), (165, 255, 255))
"""HSV range of the obstacles."""


@dataclass(frozen=True)
class FloorPatch:
    """The rectangle of floor the bird's-eye view shows, in the camera's own frame."""

    width_m: float = 1.2
    near_m: float = 1.2
    far_m: float = 3.0

    def trapezoid(self, k: Intrinsics, height_m: float, pitch_rad: float) -> np.ndarray:
        """Image pixels of the patch's corners: far-left, far-right, near-right, near-left."""
        out = []
        for fwd, side in ((self.far_m, -1), (self.far_m, 1), (self.near_m, 1), (self.near_m, -1)):
            x = side * self.width_m / 2  # right of the camera
            # Optical frame: x right, y down, z forward; the camera pitched down by pitch.
            y = height_m * math.cos(pitch_rad) - fwd * math.sin(pitch_rad)
            z = height_m * math.sin(pitch_rad) + fwd * math.cos(pitch_rad)
            out.append((k.fx * x / z + k.cx, k.fy * y / z + k.cy))
        return np.array(out, np.float32)


class BirdsEye:
    def __init__(self, k: Intrinsics, height_m: float, pitch_rad: float,
                 patch: FloorPatch | None = None,
                 size: tuple[int, int] = BEV_SIZE) -> None:  # fmt: skip
        self.patch = patch or FloorPatch()
        self.size = size
        w, h = size
        src = self.patch.trapezoid(k, height_m, pitch_rad)
        dst = np.array([(0, 0), (w - 1, 0), (w - 1, h - 1), (0, h - 1)], np.float32)
        self.homography = cv2.getPerspectiveTransform(src, dst)
        self.m_per_px = (self.patch.width_m / w, (self.patch.far_m - self.patch.near_m) / h)

    def warp(self, bgr: np.ndarray) -> np.ndarray:
        return cv2.warpPerspective(bgr, self.homography, self.size, flags=cv2.INTER_LINEAR)

    def masks(self, bev_bgr: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Binary (0/1 uint8) obstacle and target maps of a bird's-eye image."""
        hsv = cv2.cvtColor(bev_bgr, cv2.COLOR_BGR2HSV)
        obstacles = cv2.inRange(hsv, np.array(PURPLE[0]), np.array(PURPLE[1])) // 255
        target = cv2.inRange(hsv, np.array(GREEN[0]), np.array(GREEN[1])) // 255
        return obstacles, target

    def __call__(self, bgr: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        return self.masks(self.warp(bgr))

    def target_xy(self, target: np.ndarray, min_px: int = 50) -> tuple[float, float] | None:
        """The target's centre as (forward, left) metres from the camera, or None if unseen."""
        m = cv2.moments(target, binaryImage=True)
        if m["m00"] < min_px:
            return None
        u, v = m["m10"] / m["m00"], m["m01"] / m["m00"]
        w = self.size[0]
        forward = self.patch.far_m - v * self.m_per_px[1]
        left = (w / 2 - u) * self.m_per_px[0]
        return forward, left

    def cells(self, obstacles: np.ndarray, x: float, y: float, heading: float,
              shape: tuple[int, int], cell_m: float) -> np.ndarray:  # fmt: skip
        """Flat map cells under the obstacle pixels, for a camera at (x, y) facing heading."""
        v, u = np.nonzero(obstacles)
        w, _ = self.size
        fwd = self.patch.far_m - (v + 0.5) * self.m_per_px[1]
        left = (w / 2 - u - 0.5) * self.m_per_px[0]
        wx = x + fwd * math.cos(heading) - left * math.sin(heading)
        wy = y + fwd * math.sin(heading) + left * math.cos(heading)
        rows = shape[0] - 1 - np.floor(wy / cell_m).astype(np.int64)
        cols = np.floor(wx / cell_m).astype(np.int64)
        ok = (rows >= 0) & (rows < shape[0]) & (cols >= 0) & (cols < shape[1])
        return np.unique(rows[ok] * shape[1] + cols[ok])
