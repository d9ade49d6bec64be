"""Frames on disk: a depth PNG and a JSON beside it, the layout RGB-D tools use.

``DIR/<name>.png`` is a 16-bit single-channel PNG of depth in millimetres (0 = no depth),
as ROS's ``16UC1`` depth images and the TUM/Redwood RGB-D sets store it;
``DIR/<name>.json`` holds the camera's intrinsics, its pose and the frame's stamp; an
optional ``DIR/<name>_color.png`` is the colour image. The JSON is validated at the edge
with pydantic; a frame that cannot be read is refused whole (``FrameRejected``,
``UNREADABLE`` or ``NO_INTRINSICS``), never half used.

JSON::

    {"stamp": 1732600000.1,
     "intrinsics": {"width": 640, "height": 480, "fx": 381.4, "fy": 381.4,
                    "cx": 319.5, "cy": 239.5, "depth_scale": 0.001},
     "pose": {"position": [x, y, z], "orientation": [qx, qy, qz, qw]}}
"""

from __future__ import annotations

import json
from collections.abc import Callable, Iterator
from pathlib import Path

import numpy as np
from pydantic import BaseModel, ConfigDict, Field, ValidationError

from .camera_model import CameraPose, Intrinsics
from .frame import DepthFrame, FrameRejected, Refusal

Finite = Field(allow_inf_nan=False)


class _Strict(BaseModel):
    model_config = ConfigDict(extra="forbid", frozen=True)


class IntrinsicsDoc(_Strict):
    width: int = Field(gt=0, le=8192)
    height: int = Field(gt=0, le=8192)
    fx: float = Field(gt=0, allow_inf_nan=False)
    fy: float = Field(gt=0, allow_inf_nan=False)
    cx: float = Finite
    cy: float = Finite
    depth_scale: float = Field(default=0.001, gt=0, allow_inf_nan=False)


class PoseDoc(_Strict):
    position: tuple[float, float, float]
    orientation: tuple[float, float, float, float] = Field(description="x, y, z, w")


class FrameDoc(_Strict):
    stamp: float = Field(ge=0, allow_inf_nan=False)
    intrinsics: IntrinsicsDoc | None = None
    pose: PoseDoc | None = None


def write_frame(folder: Path, name: str, frame: DepthFrame) -> None:
    import cv2

    if frame.intrinsics is None or frame.pose is None:
        raise ValueError("a frame is written with its intrinsics and pose")
    folder.mkdir(parents=True, exist_ok=True)
    depth = frame.depth
    if depth.dtype != np.uint16:
        mm = np.nan_to_num(depth / frame.intrinsics.depth_scale, nan=0, posinf=0, neginf=0)
        depth = np.clip(np.round(mm), 0, 65535).astype(np.uint16)
    if not cv2.imwrite(str(folder / f"{name}.png"), depth):
        raise OSError(f"could not write {folder / name}.png")
    if frame.color is not None:
        cv2.imwrite(str(folder / f"{name}_color.png"), frame.color)
    k, p = frame.intrinsics, frame.pose
    doc = FrameDoc(
        stamp=frame.stamp,
        intrinsics=IntrinsicsDoc(
            width=k.width,
            height=k.height,
            fx=k.fx,
            fy=k.fy,
            cx=k.cx,
            cy=k.cy,
            depth_scale=k.depth_scale,
        ),
        pose=PoseDoc(position=p.position, orientation=p.orientation),
    )
    (folder / f"{name}.json").write_text(doc.model_dump_json(indent=1) + "\n")


Buffer = Callable[[int, int], np.ndarray]
"""Given a frame's height and width, the uint16 array its depth is to be read into."""


def read_frame(json_path: Path, into: Buffer | None = None) -> DepthFrame:
    """One frame from its JSON and the PNG beside it; ``FrameRejected`` if unusable.

    ``into`` (``OccupancyMapper.depth_buffer``): a depth of the size its intrinsics give is
    put there, so the frame reaches the device with no copy on its path: the reader's copy
    rides with its decode, before the frame is handed over. OpenCV's ``imread`` can decode
    into a given array, but then says nothing when the file is unreadable (the array is left
    as it was: the last frame's depth), so the depth is decoded into its own array, checked,
    then copied. A frame so read holds the buffer until the next is read into it."""
    import cv2

    try:
        doc = FrameDoc.model_validate_json(json_path.read_bytes())
    except (OSError, ValidationError, json.JSONDecodeError) as exc:
        first = str(exc).splitlines()[0][:200]
        raise FrameRejected(Refusal.UNREADABLE, f"{json_path.name}: {first}") from exc
    png = json_path.with_suffix(".png")
    depth = cv2.imread(str(png), cv2.IMREAD_UNCHANGED)
    if depth is None:
        raise FrameRejected(Refusal.UNREADABLE, f"{png.name}: not a readable image")
    if depth.dtype != np.uint16 or depth.ndim != 2:
        why = f"{png.name}: {depth.dtype} with {depth.ndim} dims, not 16-bit single channel"
        raise FrameRejected(Refusal.BAD_DEPTH, why)
    color_path = json_path.with_name(json_path.stem + "_color.png")
    color = cv2.imread(str(color_path), cv2.IMREAD_COLOR) if color_path.exists() else None
    intr = pose = None
    try:
        if doc.intrinsics is not None:
            intr = Intrinsics(**doc.intrinsics.model_dump())
        if doc.pose is not None:
            pose = CameraPose(doc.pose.position, doc.pose.orientation)
    except ValueError as exc:
        raise FrameRejected(Refusal.UNREADABLE, f"{json_path.name}: {exc}") from exc
    if into is not None and intr is not None and depth.shape == (intr.height, intr.width):
        buf = into(intr.height, intr.width)
        np.copyto(buf, depth)
        depth = buf
    return DepthFrame(depth, intr, pose, doc.stamp, color)


def frame_files(folder: Path) -> list[Path]:
    """The frames' JSON files of ``folder``, in name order (zero-padded names sort by time)."""
    if not folder.is_dir():
        raise FileNotFoundError(f"{folder} is not a folder of frames")
    return sorted(p for p in folder.glob("*.json"))


def read_frames(folder: Path, into: Buffer | None = None) -> Iterator[DepthFrame | FrameRejected]:
    """Every frame of ``folder``, or the refusal of one that cannot be read, in order
    (``into``: as ``read_frame``'s; take each frame before the next is read)."""
    for path in frame_files(folder):
        try:
            yield read_frame(path, into)
        except FrameRejected as exc:
            yield exc
