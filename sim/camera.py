"""A simulated RGB-D camera: depth and colour images of a ``Scene3D`` from a pose.

Each pixel's ray is walked through the map's cells (Amanatides & Woo's grid traversal) and
meets the first cell slab or the floor it passes; depth is the optical-axis distance, as a
depth camera reports it. Then what real depth cameras do to it: noise whose spread grows
with the square of the range (structured light and stereo both do; 1 mm + 2.5 mm/m² here,
about a RealSense D435's at 1-3 m), pixels past ``max_depth_m`` and a random share of the
rest missing (0), and millimetres in a 16-bit image. The colour image follows seed 004's
scene (Rettkowski et al., §V): obstacles purple, the target green, and a textured floor and
walls so that feature matching has something to find.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numba import njit

from mapper.camera_model import CameraPose, Intrinsics
from mapper.frame import DepthFrame

from .scene3d import BOX, PERSON, TABLE, TARGET, WALL, Scene3D

SEED000_INTRINSICS = Intrinsics.from_fov(640, 480, 80.0)
"""Seed 000's sensor: an 80° field of view, at 640 x 480."""
CHEST_HEIGHT_M = 1.3
CHEST_PITCH_DEG = 30.0
"""A chest camera tilted down enough to see the floor from about 0.7 m ahead."""


@njit(cache=True, nogil=True)
def _hash(a, b):
    h = (a * 73856093) ^ (b * 19349663)
    h = (h ^ (h >> 13)) * 1274126177
    return ((h ^ (h >> 16)) & 0xFFFF) / 65535.0


INSET_M = 0.015
"""Obstacle faces that border free floor sit this far inside their cell: real things do not
line up with the grid, and a face exactly on a cell boundary would put half its noisy
points into the free cell in front."""


@njit(cache=True, nogil=True)
def _axis(o, d, lo, hi):
    """Ray parameter interval inside [lo, hi] along one axis (empty: lo_t > hi_t)."""
    if d != 0:
        ta, tb = (lo - o) / d, (hi - o) / d
        return min(ta, tb), max(ta, tb)
    if lo <= o <= hi:
        return -1e30, 1e30
    return 1.0, -1.0


@njit(cache=True, nogil=True)
def _box_entry(r, c, cam, dx, dy, dz, z_lo, z_hi, cell, t0, t1):
    """Where the ray enters cell (r, c)'s obstacle box, or -1; sides facing an empty
    neighbour are inset by INSET_M."""
    rows, cols = z_hi.shape
    x0, y0 = c * cell, (rows - 1 - r) * cell
    x1, y1 = x0 + cell, y0 + cell
    if c > 0 and z_hi[r, c - 1] == 0:
        x0 += INSET_M
    if c < cols - 1 and z_hi[r, c + 1] == 0:
        x1 -= INSET_M
    if r < rows - 1 and z_hi[r + 1, c] == 0:
        y0 += INSET_M
    if r > 0 and z_hi[r - 1, c] == 0:
        y1 -= INSET_M
    ax, bx = _axis(cam[0], dx, x0, x1)
    ay, by = _axis(cam[1], dy, y0, y1)
    az, bz = _axis(cam[2], dz, z_lo[r, c], z_hi[r, c])
    a = max(max(t0, ax), max(ay, az))
    b = min(min(t1, bx), min(by, bz))
    return a if a <= b else -1.0


@njit(cache=True, nogil=True)
def _render(rot, cam, fx, fy, cx, cy, width, height, z_lo, z_hi, kind, mark, cell, max_d):
    rows, cols = z_hi.shape
    depth = np.zeros((height, width), np.float32)
    color = np.zeros((height, width, 3), np.uint8)
    inv = 1.0 / cell
    for v in range(height):
        for u in range(width):
            ox, oy = (u - cx) / fx, (v - cy) / fy
            dx = rot[0, 0] * ox + rot[0, 1] * oy + rot[0, 2]
            dy = rot[1, 0] * ox + rot[1, 1] * oy + rot[1, 2]
            dz = rot[2, 0] * ox + rot[2, 1] * oy + rot[2, 2]
            ix, iy = math.floor(cam[0] * inv), math.floor(cam[1] * inv)
            sx = 1 if dx > 0 else -1
            sy = 1 if dy > 0 else -1
            tdx = abs(cell / dx) if dx != 0 else 1e30
            tdy = abs(cell / dy) if dy != 0 else 1e30
            nx = ((ix + (sx > 0)) * cell - cam[0]) / dx if dx != 0 else 1e30
            ny = ((iy + (sy > 0)) * cell - cam[1]) / dy if dy != 0 else 1e30
            t0, hit_t, hit_k, hit_z = 0.0, -1.0, -1, 0.0
            while t0 < max_d:
                t1 = min(nx, ny)
                r, c = rows - 1 - iy, ix
                if r < 0 or r >= rows or c < 0 or c >= cols:
                    break
                if dz < 0:  # the floor, inside this cell
                    tf = -cam[2] / dz
                    if t0 <= tf <= t1:
                        hit_t, hit_k = tf, -1
                if z_hi[r, c] > 0:
                    a = _box_entry(r, c, cam, dx, dy, dz, z_lo, z_hi, cell, t0, t1)
                    if a >= 0 and (hit_t < 0 or a <= hit_t):
                        hit_t, hit_k, hit_z = a, kind[r, c], cam[2] + dz * a
                if hit_t >= 0:
                    break
                t0 = t1
                if nx < ny:
                    nx += tdx
                    ix += sx
                else:
                    ny += tdy
                    iy += sy
            if hit_t < 0 or hit_t > max_d:
                continue
            depth[v, u] = hit_t  # the ray's optical z is 1: t is the depth
            px, py = cam[0] + dx * hit_t, cam[1] + dy * hit_t
            gx, gy = math.floor(px * 20.0), math.floor(py * 20.0)
            fine = _hash(gx, gy)
            if hit_k < 0:
                r, c = rows - 1 - math.floor(py * inv), math.floor(px * inv)
                if 0 <= r < rows and 0 <= c < cols and mark[r, c] == TARGET:
                    color[v, u, 0], color[v, u, 1], color[v, u, 2] = 40, 190 + 40 * fine, 40
                else:
                    tile = _hash(math.floor(px * 4.0), math.floor(py * 4.0))
                    g = 90 + 60 * tile + 30 * fine
                    color[v, u, 0], color[v, u, 1], color[v, u, 2] = g, g, g + 5
            elif hit_k == WALL:
                g = 170 + 40 * _hash(gx + gy, int(hit_z * 20.0))
                color[v, u, 0], color[v, u, 1], color[v, u, 2] = g - 30, g, g + 10
            elif hit_k in (BOX, TABLE):
                color[v, u, 0], color[v, u, 1], color[v, u, 2] = 150 + 40 * fine, 30, 130
            elif hit_k == PERSON:
                color[v, u, 0], color[v, u, 1], color[v, u, 2] = 60, 80 + 40 * fine, 150
    return depth, color


@dataclass(frozen=True)
class RgbdCamera:
    """The camera's model: intrinsics, how it is worn, and how its depth goes wrong."""

    intrinsics: Intrinsics = SEED000_INTRINSICS
    mount_height_m: float = CHEST_HEIGHT_M
    pitch_deg: float = CHEST_PITCH_DEG
    max_depth_m: float = 8.0
    noise_a_m: float = 0.001
    noise_b: float = 0.0025
    """Depth noise sd = a + b · depth² (metres)."""
    missing: float = 0.02
    """Share of pixels with no depth (specular, dark, edge dropouts)."""

    def pose(self, x: float, y: float, heading: float, pitch_deg: float | None = None,
             roll_deg: float = 0.0) -> CameraPose:  # fmt: skip
        pitch = math.radians(self.pitch_deg if pitch_deg is None else pitch_deg)
        return CameraPose.level(x, y, self.mount_height_m, heading, pitch, math.radians(roll_deg))

    def render(self, scene: Scene3D, pose: CameraPose, stamp: float,
               rng: np.random.Generator | None = None, *,
               reported_pose: CameraPose | None = None,
               out: np.ndarray | None = None) -> DepthFrame:  # fmt: skip
        """The frame seen from ``pose``; it reports ``reported_pose`` (default: the true
        one), e.g. the mounting's nominal pitch while the camera is really tilted. ``out``:
        the uint16 array to write the depth into (``OccupancyMapper.depth_buffer``), in
        place of one of its own; the depth's cast writes it there, no copy."""
        k = self.intrinsics
        depth, color = _render(
            pose.world_from_optical(), np.asarray(pose.position, np.float64), k.fx, k.fy, k.cx,
            k.cy, k.width, k.height, scene.z_lo, scene.z_hi, scene.kind, scene.mark,
            float(scene.cell_m), float(self.max_depth_m),
        )  # fmt: skip
        if rng is not None:
            sd = self.noise_a_m + self.noise_b * depth * depth
            hit = depth > 0  # no noise makes a depth where the ray met nothing
            depth = np.where(hit, depth + rng.standard_normal(depth.shape, np.float32) * sd, 0)
            depth[rng.random(depth.shape, np.float32) < self.missing] = 0.0
        mm = np.clip(np.round(depth / k.depth_scale), 0, 65535)
        if out is None:
            mm = mm.astype(np.uint16)
        else:  # the same cast, into the buffer
            np.copyto(out, mm, casting="unsafe")
            mm = out
        mm[depth <= 0] = 0
        return DepthFrame(mm, k, reported_pose or pose, stamp, color)
