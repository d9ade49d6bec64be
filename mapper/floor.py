"""The floor plane: from the camera's mounting, refined by RANSAC on the frame's own points.

The pose says where the floor should be (z = 0 in the world). A chest camera slips and
tilts with every step, so the mapper samples a sparse grid of pixels, keeps those the
nominal pose puts near the floor, and fits a plane to them with RANSAC (three points per
hypothesis, inliers within ``inlier_m``, the normal no further than ``max_tilt`` from up,
then a least-squares refit on the inliers). The fitted plane gives a rotation that levels
it and the height of the floor under the camera; a frame that shows too little floor keeps
the nominal plane.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from .camera_model import Intrinsics


@dataclass(frozen=True)
class FloorFit:
    rotation: np.ndarray
    """3x3 correction applied about the camera: the fitted normal becomes world up."""
    floor_z: float
    """Height of the fitted floor in the corrected frame (0 for the nominal floor)."""
    tilt_deg: float
    """Angle between the fitted normal and the nominal up."""
    inliers: int
    fitted: bool


NOMINAL = FloorFit(np.eye(3), 0.0, 0.0, 0, False)
SCORE_POINTS = 600


def sample_points(depth: np.ndarray, scale: float, intr: Intrinsics, rot: np.ndarray,
                  t: np.ndarray, step: int) -> np.ndarray:  # fmt: skip
    """World points (nominal pose) of every ``step``-th pixel with a usable depth."""
    return points_of(depth[::step, ::step], step, scale, intr, rot, t)


def points_of(sub: np.ndarray, step: int, scale: float, intr: Intrinsics, rot: np.ndarray,
              t: np.ndarray) -> np.ndarray:  # fmt: skip
    """``sample_points`` of an image already cut to every ``step``-th pixel (``sub``): the
    few kB a fit off the frame's path keeps of the frame."""
    d = sub.astype(np.float64) * scale
    v, u = np.mgrid[0 : sub.shape[0] * step : step, 0 : sub.shape[1] * step : step]
    ok = np.isfinite(d) & (d > 0) & (d < 1e4)
    d, u, v = d[ok], u[ok], v[ok]
    q = np.stack(((u - intr.cx) / intr.fx * d, (v - intr.cy) / intr.fy * d, d))
    return (rot @ q).T + t


def _rotation_between(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """The smallest rotation taking unit vector ``a`` onto unit vector ``b`` (Rodrigues)."""
    v = np.cross(a, b)
    s, c = float(np.linalg.norm(v)), float(a @ b)
    if s < 1e-12:
        return np.eye(3)
    k = np.array([[0, -v[2], v[1]], [v[2], 0, -v[0]], [-v[1], v[0], 0]]) / s
    return np.eye(3) + s * k + (1 - c) * (k @ k)


def fit_floor(points: np.ndarray, cam: np.ndarray, *, band_m: float = 0.6,
              inlier_m: float = 0.02, max_tilt_deg: float = 25.0, hypotheses: int = 96,
              min_inliers: int = 60, min_share: float = 0.15, max_offset_m: float = 0.2,
              rng: np.random.Generator | None = None) -> FloorFit:  # fmt: skip
    """RANSAC plane of the points near the nominal floor; ``NOMINAL`` if none is good."""
    cand = points[np.abs(points[:, 2]) < band_m]
    if len(cand) < max(min_inliers, 3):
        return NOMINAL
    rng = rng or np.random.default_rng(0)
    tri = cand[rng.integers(0, len(cand), size=(hypotheses, 3))]
    # Hypotheses are scored on at most SCORE_POINTS of the candidates (the refit uses all).
    scored = cand if len(cand) <= SCORE_POINTS else cand[rng.choice(len(cand), SCORE_POINTS, False)]
    normals = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    norm = np.linalg.norm(normals, axis=1)
    good = norm > 1e-9
    normals = normals[good] / norm[good, None]
    normals *= np.sign(normals[:, 2:3] + 1e-12)  # point them up
    cos_max = math.cos(math.radians(max_tilt_deg))
    keep = normals[:, 2] >= cos_max
    normals, anchors = normals[keep], tri[good][keep, 0]
    if len(normals) == 0:
        return NOMINAL
    offsets = -np.einsum("ij,ij->i", normals, anchors)
    # The floor passes under the camera near where the mounting says (a tilt turns the plane
    # about the camera, it hardly moves the point below it); a box's top does not.
    under = -(normals[:, 0] * cam[0] + normals[:, 1] * cam[1] + offsets) / normals[:, 2]
    dist = np.abs(scored @ normals.T + offsets)  # (points, hypotheses)
    score = np.where(np.abs(under) <= max_offset_m, (dist < inlier_m).sum(axis=0), -1)
    best = int(np.argmax(score))
    if score[best] < 0:
        return NOMINAL
    inl = cand[np.abs(cand @ normals[best] + offsets[best]) < inlier_m]
    if len(inl) < min_inliers or len(inl) < min_share * len(cand):
        return NOMINAL
    for _ in range(2):  # least squares on the inliers, then again on the refit's own inliers
        centre = inl.mean(axis=0)
        normal = np.linalg.svd(inl - centre, full_matrices=False)[2][2]
        normal = normal * (1.0 if normal[2] >= 0 else -1.0)
        near = np.abs((cand - centre) @ normal) < inlier_m
        if near.sum() < min_inliers:
            return NOMINAL
        inl = cand[near]
    if normal[2] < cos_max:
        return NOMINAL
    # Keep the mounting's floor unless the fit explains the floor points clearly better: a
    # narrow strip of floor fixes its own tilt poorly, and the pose is usually right.
    fitted_rms = float(np.sqrt(np.mean(((inl - centre) @ normal) ** 2)))
    nominal_rms = float(np.sqrt(np.mean(inl[:, 2] ** 2)))
    if nominal_rms < 1.5 * fitted_rms + 0.005:
        return FloorFit(np.eye(3), 0.0, 0.0, len(inl), False)
    up = np.array([0.0, 0.0, 1.0])
    rot = _rotation_between(normal, up)
    # Heights measured from the camera: the plane, turned about it, lies at this z.
    floor_z = float(cam[2] + normal @ (centre - cam))
    tilt = math.degrees(math.acos(min(1.0, float(normal[2]))))
    return FloorFit(rot, floor_z, tilt, len(inl), True)
