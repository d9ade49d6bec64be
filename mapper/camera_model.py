"""The camera: pinhole intrinsics and a pose in the world, as plain arrays.

Frames follow ROS REP 103/105: the world is x east, y north, z up (metres, the floor at
z = 0); the camera body is x forward, y left, z up, its pose a position and a unit
quaternion (x, y, z, w) in the world; pixels live in the optical frame (x right, y down,
z forward). Heading is the yaw of the body's x axis (0 = east, counter-clockwise), the same
angle as ``Pose.heading`` on the wire.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import cached_property

import numpy as np

OPTICAL_TO_BODY = np.array([[0.0, 0.0, 1.0], [-1.0, 0.0, 0.0], [0.0, -1.0, 0.0]])
"""Optical (x right, y down, z forward) → body (x forward, y left, z up)."""


@dataclass(frozen=True)
class Intrinsics:
    """Pinhole intrinsics of the depth image, in pixels; ``depth_scale`` metres per unit."""

    width: int
    height: int
    fx: float
    fy: float
    cx: float
    cy: float
    depth_scale: float = 0.001

    def __post_init__(self) -> None:
        numbers = (self.fx, self.fy, self.cx, self.cy, self.depth_scale)
        if self.width <= 0 or self.height <= 0:
            raise ValueError(f"image size {self.width}x{self.height} is not positive")
        if not all(math.isfinite(v) for v in numbers) or min(self.fx, self.fy) <= 0:
            raise ValueError("focal lengths must be finite and positive, centres finite")
        if self.depth_scale <= 0:
            raise ValueError("depth_scale must be positive")

    @classmethod
    def from_fov(cls, width: int, height: int, hfov_deg: float) -> Intrinsics:
        """Square pixels, the principal point at the centre, ``hfov_deg`` across."""
        f = (width / 2) / math.tan(math.radians(hfov_deg) / 2)
        return cls(width, height, f, f, (width - 1) / 2, (height - 1) / 2)

    @property
    def hfov(self) -> float:
        """Horizontal field of view, radians."""
        return 2 * math.atan2(self.width / 2, self.fx)

    def scaled(self, factor: float) -> Intrinsics:
        """The same camera at ``factor`` times the resolution."""
        return Intrinsics(
            round(self.width * factor), round(self.height * factor), self.fx * factor,
            self.fy * factor, (self.cx + 0.5) * factor - 0.5, (self.cy + 0.5) * factor - 0.5,
            self.depth_scale,
        )  # fmt: skip


def quaternion_from_ypr(yaw: float, pitch: float, roll: float = 0.0) -> tuple[float, ...]:
    """(x, y, z, w) of R = Rz(yaw) · Ry(pitch) · Rx(roll); pitch > 0 tilts the nose down."""
    cy, sy = math.cos(yaw / 2), math.sin(yaw / 2)
    cp, sp = math.cos(pitch / 2), math.sin(pitch / 2)
    cr, sr = math.cos(roll / 2), math.sin(roll / 2)
    return (
        sr * cp * cy - cr * sp * sy,
        cr * sp * cy + sr * cp * sy,
        cr * cp * sy - sr * sp * cy,
        cr * cp * cy + sr * sp * sy,
    )


def rotation_of(q: tuple[float, float, float, float] | np.ndarray) -> np.ndarray:
    """3x3 rotation of a unit quaternion (x, y, z, w); ValueError if it is not one."""
    x, y, z, w = (float(v) for v in q)
    n = math.sqrt(x * x + y * y + z * z + w * w)
    if not math.isfinite(n) or abs(n - 1.0) > 1e-3:
        raise ValueError(f"orientation is not a unit quaternion (norm {n:.4g})")
    x, y, z, w = x / n, y / n, z / n, w / n
    return np.array(
        [
            [1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
            [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
            [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)],
        ]
    )


@dataclass(frozen=True)
class CameraPose:
    """Where the camera body is and how it is turned, in the world."""

    position: tuple[float, float, float]
    orientation: tuple[float, float, float, float]
    """Unit quaternion (x, y, z, w), world ← body."""

    def __post_init__(self) -> None:
        if len(self.position) != 3 or not all(math.isfinite(v) for v in self.position):
            raise ValueError("position must be three finite numbers")
        self._rotation  # refuses a non-unit or non-finite quaternion  # noqa: B018

    @classmethod
    def level(cls, x: float, y: float, z: float, heading: float, pitch: float = 0.0,
              roll: float = 0.0) -> CameraPose:  # fmt: skip
        return cls((x, y, z), quaternion_from_ypr(heading, pitch, roll))

    @cached_property
    def _rotation(self) -> np.ndarray:
        """``rotation_of(orientation)``, made once (a frozen pose never turns): the check
        needs it, and the mapper reads it twice a frame (``world_from_optical``,
        ``heading``). A pose pickled before it existed makes it on first use."""
        return rotation_of(self.orientation)

    def world_from_optical(self) -> np.ndarray:
        """3x3 rotation taking optical-frame vectors into the world."""
        return self._rotation @ OPTICAL_TO_BODY

    @property
    def heading(self) -> float:
        """Yaw of the body's forward axis: the direction the wearer walks."""
        r = self._rotation
        return math.atan2(r[1, 0], r[0, 0])
