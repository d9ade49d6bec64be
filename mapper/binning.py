"""The per-pixel pass on the CPU: depth → 3D points → floor height → cells and rays.

One numba loop over the pixels does what seed 000's mapper does per frame ("projecting 3D
points to the floor and defining a threshold in height", §1): back-project each pixel with
the pinhole model, move it into the world with the camera's (floor-corrected) pose, and
count it in the cell under it when its height above the floor lies between the minimum and
the maximum. The same loop keeps, per bearing bin, the nearest obstacle point and the
farthest point seen free (floor, or anything past the range), which is where that bearing's
ray clears the map. ``cuda_binning.py`` is the same pass in CuPy.

The bins are bearings on the floor, not image columns: a chest camera is pitched down (30°),
so one image column fans out across the floor, its bottom pixels 20-30° further out than its
top ones near the image's edges. Binned by column, an obstacle at the bottom left ended the
ray of a column whose floor, seen far off at another bearing, was then never cleared: the
ghost of a person who walked there stayed until forgotten, and a passage closed for good.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numba import njit

MIN_DEPTH_M = 0.15
"""Nearer than this no depth camera measures (a D435 from 0.1-0.3 m): a value there is noise."""
PUSH_M = 0.002
"""How far a surface point is moved on along its ray before it is binned: a face lying on
a cell boundary then counts in the cell behind it, not the free one in front (above the
millimetre of a 16-bit depth image); small enough not to carry the far edge of a table's
top, seen at a grazing angle, into the next cell."""
TAN_LIMIT = math.tan(math.radians(85.0))
"""Bearings further out than this from the camera's yaw share the outermost bins."""


@dataclass(frozen=True)
class Window:
    """The square of map cells a frame can touch: rows ``r0..r0+side``, cols likewise."""

    r0: int
    c0: int
    side: int
    map_rows: int
    cell_m: float


@dataclass
class Binned:
    """What one frame says, in its window and per bearing bin. From the cuda pass the arrays
    are its page-locked read-back, valid until that binner's next frame: merge them first."""

    counts: np.ndarray
    """``(2, side, side)`` int32: obstacle points ([0]) and floor points ([1]) per cell."""
    hit: np.ndarray
    """``(bins, 3)``: squared range, x, y of the nearest obstacle point (inf: none), per
    bearing bin (``bearing_bins``)."""
    far: np.ndarray
    """``(bins, 3)``: squared range, x, y of the farthest free point (-1: none)."""
    valid: int
    """Pixels with a usable depth."""
    present: int | None = None
    """Pixels the frame check counts (``frame.count_valid``) where the pass counted them
    (cuda, ``Binner.counts_valid``); None where the mapper counts on the host."""


def bearing_bins(rot: np.ndarray, intr, width: int, height: int) -> tuple[float, float, float]:
    """How a point's bearing picks its bin: the camera's yaw (cos, sin) and the largest
    |tan| of a pixel's bearing from it, at the image's corners (the edges of a pinhole
    image bound its bearings). Bin = (tan + tan_max) / (2 tan_max) of the bins. Plain float
    arithmetic, as the cuda pass does the same on the device (``kernels/bin_pixels.cu``)."""
    r = np.asarray(rot, np.float64).tolist()
    ax, ay = r[0][2], r[1][2]  # the optical axis, seen from above
    n = math.sqrt(ax * ax + ay * ay)
    c, s = (ax / n, ay / n) if n > 0 else (1.0, 0.0)
    tan_max = 1e-3
    for u in (0.0, width - 1.0):
        for v in (0.0, height - 1.0):
            rx, ry = (u - intr.cx) / intr.fx, (v - intr.cy) / intr.fy
            x = r[0][0] * rx + r[0][1] * ry + r[0][2]
            y = r[1][0] * rx + r[1][1] * ry + r[1][2]
            fwd, side = x * c + y * s, -x * s + y * c
            tan_max = max(tan_max, abs(side) / fwd if fwd > 0 else TAN_LIMIT)
    return c, s, min(tan_max, TAN_LIMIT) * (1.0 + 1e-6)


@njit(cache=True, nogil=True, inline="always")
def bearing_bin(dx, dy, yaw_c, yaw_s, tan_max, bins):
    """The bin of the bearing of (dx, dy) from the camera (``bearing_bins``)."""
    fwd = dx * yaw_c + dy * yaw_s
    side = dy * yaw_c - dx * yaw_s
    t = side / fwd if fwd > 0 else (tan_max if side > 0 else -tan_max)
    b = int((t + tan_max) * (bins / (2.0 * tan_max)))
    return min(max(b, 0), bins - 1)


@njit(cache=True, nogil=True, fastmath=True, error_model="numpy")
def _bin_pixels(depth, scale, fx, fy, cx, cy, rot, t, floor_z, r0, c0, side, map_rows, cell_m,
                min_h, max_h, max_range, bins, yaw_c, yaw_s, tan_max, stride,
                min_depth):  # fmt: skip
    h, w = depth.shape
    counts = np.zeros((2, side, side), np.int32)
    hit = np.empty((bins, 3), np.float64)
    far = np.empty((bins, 3), np.float64)
    for b in range(bins):
        hit[b, 0] = np.inf
        far[b, 0] = -1.0
    valid = 0
    max_r2 = max_range * max_range
    inv = 1.0 / cell_m
    # Row and column terms of each pixel's ray, so the loop only multiplies and adds.
    rxs = (np.arange(w) - cx) / fx
    ax, ay, az = rot[0, 0] * rxs, rot[1, 0] * rxs, rot[2, 0] * rxs
    top = map_rows - 1 - r0
    for v in range(0, h, stride):
        ry = (v - cy) / fy
        bx = rot[0, 1] * ry + rot[0, 2]
        by = rot[1, 1] * ry + rot[1, 2]
        bz = rot[2, 1] * ry + rot[2, 2]
        for u in range(0, w, stride):
            d = depth[v, u] * scale
            if not (d >= min_depth) or d > 1e4:  # 0, too near, NaN or inf: missing
                continue
            valid += 1
            dx = (ax[u] + bx) * d
            dy = (ay[u] + by) * d
            pz = (az[u] + bz) * d + t[2] - floor_z
            px, py = dx + t[0], dy + t[1]
            r2 = dx * dx + dy * dy
            b = bearing_bin(dx, dy, yaw_c, yaw_s, tan_max, bins)
            if r2 > max_r2:  # past the range: free as far as the range, no obstacle
                if max_r2 > far[b, 0]:
                    k = max_range / np.sqrt(r2)
                    far[b, 0], far[b, 1], far[b, 2] = max_r2, t[0] + dx * k, t[1] + dy * k
                continue
            if pz < min_h:
                if r2 > far[b, 0]:
                    far[b, 0], far[b, 1], far[b, 2] = r2, px, py
                row = top - int(np.floor(py * inv))
                col = int(np.floor(px * inv)) - c0
                if 0 <= row < side and 0 <= col < side:
                    counts[1, row, col] += 1
            elif pz <= max_h:
                if r2 < hit[b, 0]:
                    hit[b, 0], hit[b, 1], hit[b, 2] = r2, px, py
                # A face on a cell boundary belongs to the cell behind it: push the point
                # PUSH_M on along its ray before binning it.
                k = 1.0 + PUSH_M / np.sqrt(r2 + 1e-12)
                row = top - int(np.floor((t[1] + dy * k) * inv))
                col = int(np.floor((t[0] + dx * k) * inv)) - c0
                if 0 <= row < side and 0 <= col < side:
                    counts[0, row, col] += 1
    return counts, hit, far, valid


def bin_frame_cpu(depth: np.ndarray, scale: float, intr, rot: np.ndarray, t: np.ndarray,
                  floor_z: float, win: Window, min_h: float, max_h: float, max_range: float,
                  cols_per_bin: int, stride: int,
                  min_depth: float = MIN_DEPTH_M) -> Binned:  # fmt: skip
    h, w = depth.shape
    bins = (w + cols_per_bin - 1) // cols_per_bin
    yaw_c, yaw_s, tan_max = bearing_bins(rot, intr, w, h)
    counts, hit, far, valid = _bin_pixels(
        depth, float(scale), float(intr.fx), float(intr.fy), float(intr.cx), float(intr.cy),
        np.ascontiguousarray(rot, np.float64), np.ascontiguousarray(t, np.float64),
        float(floor_z), win.r0, win.c0, win.side, win.map_rows, float(win.cell_m),
        float(min_h), float(max_h), float(max_range), bins, yaw_c, yaw_s, tan_max,
        int(stride), float(min_depth),
    )  # fmt: skip
    return Binned(counts, hit, far, int(valid))


@njit(cache=True, nogil=True)
def clear_rays(hit, far, cam_x, cam_y, r0, c0, side, map_rows, cell_m, clearance):
    """``(side, side)`` uint8: 1 where some bearing bin's ray passed before its first hit.

    A ray ends ``clearance`` short of the nearest obstacle point of its bin (the cell
    holding the obstacle's face is not the ray's to clear), or at the farthest free point
    when the bin saw no obstacle. A bin with no valid depth clears nothing.
    """
    free = np.zeros((side, side), np.uint8)
    step = cell_m * 0.5
    inv = 1.0 / cell_m
    for b in range(hit.shape[0]):
        if hit[b, 0] < np.inf:
            tx, ty = hit[b, 1], hit[b, 2]
            end = np.sqrt(hit[b, 0]) - clearance
        elif far[b, 0] >= 0.0:
            tx, ty = far[b, 1], far[b, 2]
            end = np.sqrt(far[b, 0])
        else:
            continue
        full = np.sqrt((tx - cam_x) ** 2 + (ty - cam_y) ** 2)
        if full <= 0.0 or end <= 0.0:
            continue
        ux, uy = (tx - cam_x) / full, (ty - cam_y) / full
        n = int(end / step) + 1
        for i in range(n):
            s = min(i * step, end)
            x, y = cam_x + ux * s, cam_y + uy * s
            row = map_rows - 1 - int(np.floor(y * inv)) - r0
            col = int(np.floor(x * inv)) - c0
            if 0 <= row < side and 0 <= col < side:
                free[row, col] = 1
    return free
