"""One depth frame as the mapper takes it, and the checks that refuse a bad one whole."""

from __future__ import annotations

import math
from dataclasses import dataclass
from enum import StrEnum

import numpy as np

from .camera_model import CameraPose, Intrinsics

DEPTH_DTYPES = frozenset(np.dtype(t) for t in (np.uint16, np.float32, np.float64))
"""A depth's types (native byte order), as dtypes: a set's lookup, no type converted per frame."""
UINT16 = np.dtype(np.uint16)


@dataclass(frozen=True)
class DepthFrame:
    depth: np.ndarray
    """``(height, width)``: ``uint16`` in units of ``intrinsics.depth_scale`` (0 = missing)
    or ``float32`` metres (0, NaN or inf = missing)."""
    intrinsics: Intrinsics | None
    pose: CameraPose | None
    stamp: float
    """Seconds since the Unix epoch, when the frame was taken."""
    color: np.ndarray | None = None
    """Optional ``(height, width, 3)`` uint8 BGR image of the same view."""


class Refusal(StrEnum):
    """Why a frame was refused (counted by reason; the map is left as it was)."""

    WRONG_SIZE = "wrong_size"
    NO_INTRINSICS = "no_intrinsics"
    NO_POSE = "no_pose"
    BAD_DEPTH = "bad_depth"
    NO_DEPTH = "no_depth"
    STALE = "stale"
    POSE_JUMP = "pose_jump"
    UNREADABLE = "unreadable"
    NO_COLOUR = "no_colour"  # a colour-camera mode (seed 004) got a frame without colour


class FrameRejected(ValueError):
    def __init__(self, refusal: Refusal, reason: str) -> None:
        super().__init__(f"{refusal}: {reason}")
        self.refusal = refusal
        self.reason = reason


@dataclass(frozen=True)
class FrameLimits:
    min_valid_share: float = 0.01
    """Fewer usable pixels than this share: the camera saw nothing (covered, blinded)."""
    max_speed_mps: float = 3.0
    """Faster than a running pedestrian between two frames: the pose jumped."""
    jump_margin_m: float = 0.5
    """Slack on top of the speed (pose noise, a frame after a pause)."""


def check_frame(frame: DepthFrame, limits: FrameLimits, last_stamp: float | None,
                last_xy: tuple[float, float] | None) -> tuple[Intrinsics, CameraPose]:  # fmt: skip
    """The frame's intrinsics and pose, or ``FrameRejected`` saying why it cannot be used."""
    intr, pose = check_header(frame, last_stamp)
    check_depth(count_valid(frame.depth), frame.depth.size, limits)
    check_motion(pose, frame.stamp, limits, last_stamp, last_xy)
    return intr, pose


def check_header(frame: DepthFrame,
                 last_stamp: float | None) -> tuple[Intrinsics, CameraPose]:  # fmt: skip
    """``check_frame``'s rules that read no pixel: intrinsics, pose, the depth's type and
    size, the stamp. A mapper whose GPU pass counts the pixels (``backends``) checks these
    first and the rest, in the same order, once the pass is back."""
    intr, pose = frame.intrinsics, frame.pose
    if intr is None:
        raise FrameRejected(Refusal.NO_INTRINSICS, "the frame has no intrinsics")
    if pose is None:
        raise FrameRejected(Refusal.NO_POSE, "the frame has no camera pose")
    depth = frame.depth
    if not isinstance(depth, np.ndarray) or depth.ndim != 2:
        raise FrameRejected(Refusal.BAD_DEPTH, "depth must be a 2-D array")
    if depth.dtype not in DEPTH_DTYPES:
        raise FrameRejected(Refusal.BAD_DEPTH, f"depth of dtype {depth.dtype} (uint16 or float)")
    if depth.shape != (intr.height, intr.width):
        why = f"depth {depth.shape[1]}x{depth.shape[0]}, intrinsics {intr.width}x{intr.height}"
        raise FrameRejected(Refusal.WRONG_SIZE, why)
    if not math.isfinite(frame.stamp) or frame.stamp < 0:
        raise FrameRejected(Refusal.STALE, f"stamp {frame.stamp!r} is not a time")
    if last_stamp is not None and frame.stamp <= last_stamp:
        why = f"stamp {frame.stamp:.3f} is not after the last frame's {last_stamp:.3f}"
        raise FrameRejected(Refusal.STALE, why)
    return intr, pose


def count_valid(depth: np.ndarray) -> int:
    """Pixels that hold a depth: non-zero (uint16), or finite and positive (float). The cuda
    pass counts by the same rule (``kernels/bin_pixels.cu``'s ``present``)."""
    if depth.dtype == np.uint16:
        return int(np.count_nonzero(depth))
    return int(np.count_nonzero(np.isfinite(depth) & (depth > 0)))


def check_depth(valid: int, size: int, limits: FrameLimits) -> None:
    if valid < limits.min_valid_share * size:
        raise FrameRejected(Refusal.NO_DEPTH, f"{valid} of {size} pixels have a depth")


def check_motion(pose: CameraPose, stamp: float, limits: FrameLimits, last_stamp: float | None,
                 last_xy: tuple[float, float] | None) -> None:  # fmt: skip
    if last_xy is not None and last_stamp is not None:
        moved = math.hypot(pose.position[0] - last_xy[0], pose.position[1] - last_xy[1])
        allowed = limits.max_speed_mps * (stamp - last_stamp) + limits.jump_margin_m
        if moved > allowed:
            why = f"the camera moved {moved:.2f} m in {stamp - last_stamp:.3f} s"
            raise FrameRejected(Refusal.POSE_JUMP, why)
