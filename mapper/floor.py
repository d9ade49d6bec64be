"""The floor plane: from the camera's mounting, refined by RANSAC on the frame's own points.

The pose says where the floor should be (z = 0 in the world). A chest camera slips and
tilts with every step, so the mapper samples a sparse grid of pixels, keeps those the
nominal pose puts near the floor, and fits a plane to them with RANSAC (three points per
hypothesis, inliers within ``inlier_m``, the normal no further than ``max_tilt`` from up,
then a least-squares refit on the inliers). The fitted plane gives a rotation that levels
it and the height of the floor under the camera; a frame that shows too little floor keeps
the nominal plane.

The fit runs off the frame's path on a worker thread (``MapperSettings.floor_async``), so it
is one numba pass that holds no GIL: the frame's own Python work never waits for it.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numba import njit

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
    return _points(sub, step, float(scale), float(intr.fx), float(intr.fy), float(intr.cx),
                   float(intr.cy), np.ascontiguousarray(rot, np.float64),
                   np.ascontiguousarray(t, np.float64))  # fmt: skip


@njit(cache=True, nogil=True)
def _points(sub, step, scale, fx, fy, cx, cy, rot, t):
    out = np.empty((sub.size, 3), np.float64)
    n = 0
    for i in range(sub.shape[0]):
        for j in range(sub.shape[1]):
            d = sub[i, j] * scale
            if not (d > 0 and d < 1e4):  # 0, NaN or inf: missing
                continue
            qx, qy = (j * step - cx) / fx * d, (i * step - cy) / fy * d
            for k in range(3):
                out[n, k] = rot[k, 0] * qx + rot[k, 1] * qy + rot[k, 2] * d + t[k]
            n += 1
    return out[:n]


def _rotation_between(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """The smallest rotation taking unit vector ``a`` onto unit vector ``b`` (Rodrigues)."""
    v = np.cross(a, b)
    s, c = float(np.linalg.norm(v)), float(a @ b)
    if s < 1e-12:
        return np.eye(3)
    k = np.array([[0, -v[2], v[1]], [v[2], 0, -v[0]], [-v[1], v[0], 0]]) / s
    return np.eye(3) + s * k + (1 - c) * (k @ k)


@njit(cache=True, nogil=True)
def _least_axis(m):
    """The eigenvector of symmetric 3 x 3 ``m`` with the least eigenvalue, by cyclic Jacobi
    rotations (the plane's normal: numba's LAPACK needs SciPy, which this project lacks)."""
    a = m.copy()
    v = np.eye(3)
    for _ in range(30):
        if a[0, 1] ** 2 + a[0, 2] ** 2 + a[1, 2] ** 2 <= 1e-30 * (np.sum(a * a) + 1e-300):
            break
        for p, q in ((0, 1), (0, 2), (1, 2)):
            if a[p, q] == 0.0:
                continue
            theta = (a[q, q] - a[p, p]) / (2.0 * a[p, q])
            t = (1.0 if theta >= 0 else -1.0) / (abs(theta) + math.sqrt(theta * theta + 1.0))
            c = 1.0 / math.sqrt(t * t + 1.0)
            s = t * c
            for k in range(3):
                akp, akq = a[k, p], a[k, q]
                a[k, p], a[k, q] = c * akp - s * akq, s * akp + c * akq
            for k in range(3):
                apk, aqk = a[p, k], a[q, k]
                a[p, k], a[q, k] = c * apk - s * aqk, s * apk + c * aqk
            for k in range(3):
                vkp, vkq = v[k, p], v[k, q]
                v[k, p], v[k, q] = c * vkp - s * vkq, s * vkp + c * vkq
    i = 0
    for k in range(1, 3):
        if a[k, k] < a[i, i]:
            i = k
    return v[:, i].copy()


@njit(cache=True, nogil=True)
def _dot3(a, b):
    """``a @ b`` of two 3-vectors: numba's ``@`` calls BLAS through SciPy."""
    return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]


@njit(cache=True, nogil=True)
def _near(cand, normal, offset, inlier_m):
    keep = np.empty(cand.shape[0], np.bool_)
    for i in range(cand.shape[0]):
        d = cand[i, 0] * normal[0] + cand[i, 1] * normal[1] + cand[i, 2] * normal[2] + offset
        keep[i] = abs(d) < inlier_m
    return keep


@njit(cache=True, nogil=True)
def _ransac(points, cam, band_m, inlier_m, cos_max, hypotheses, min_inliers, min_share,
            max_offset_m, score_points, seed):  # fmt: skip
    """The fit proper. Returns (0: none, 1: the mounting's floor kept, 2: fitted), the
    normal, a point of the plane and the inliers."""
    normal, centre = np.zeros(3), np.zeros(3)
    cand = points[np.abs(points[:, 2]) < band_m]
    n = cand.shape[0]
    if n < max(min_inliers, 3):
        return 0, normal, centre, 0
    np.random.seed(seed)  # numba's generator, one per thread: the same draw every fit
    # Hypotheses are scored on at most score_points of the candidates (the refit uses all).
    scored = cand
    if n > score_points:
        pick = np.arange(n)
        for i in range(score_points):  # a partial shuffle: a sample without replacement
            j = np.random.randint(i, n)
            pick[i], pick[j] = pick[j], pick[i]
        scored = cand[pick[:score_points]]
    best, best_n, best_off = -1, np.zeros(3), 0.0
    for _ in range(hypotheses):
        p0 = cand[np.random.randint(0, n)]
        e1 = cand[np.random.randint(0, n)] - p0
        e2 = cand[np.random.randint(0, n)] - p0
        nrm = np.cross(e1, e2)
        norm = math.sqrt(_dot3(nrm, nrm))
        if norm <= 1e-9:
            continue
        nrm = nrm / norm if nrm[2] >= 0 else -nrm / norm  # point it up
        if nrm[2] < cos_max:
            continue
        off = -_dot3(nrm, p0)
        # The floor passes under the camera near where the mounting says (a tilt turns the
        # plane about the camera, it hardly moves the point below it); a box's top does not.
        if abs(-(nrm[0] * cam[0] + nrm[1] * cam[1] + off) / nrm[2]) > max_offset_m:
            continue
        score = int(np.sum(_near(scored, nrm, off, inlier_m)))
        if score > best:
            best, best_n, best_off = score, nrm, off
    if best < 0:
        return 0, normal, centre, 0
    inl = cand[_near(cand, best_n, best_off, inlier_m)]
    if len(inl) < min_inliers or len(inl) < min_share * n:
        return 0, normal, centre, 0
    for _ in range(2):  # least squares on the inliers, then again on the refit's own inliers
        centre = np.zeros(3)
        for k in range(3):
            centre[k] = inl[:, k].mean()
        cov = np.zeros((3, 3))
        for i in range(inl.shape[0]):
            for j in range(3):
                for k in range(3):
                    cov[j, k] += (inl[i, j] - centre[j]) * (inl[i, k] - centre[k])
        normal = _least_axis(cov)
        if normal[2] < 0:
            normal = -normal
        near = _near(cand, normal, -_dot3(normal, centre), inlier_m)
        if near.sum() < min_inliers:
            return 0, normal, centre, 0
        inl = cand[near]
    if normal[2] < cos_max:
        return 0, normal, centre, 0
    # Keep the mounting's floor unless the fit explains the floor points clearly better: a
    # narrow strip of floor fixes its own tilt poorly, and the pose is usually right.
    fitted_sq = nominal_sq = 0.0
    for i in range(inl.shape[0]):
        fitted_sq += _dot3(inl[i] - centre, normal) ** 2
        nominal_sq += inl[i, 2] ** 2
    fitted_rms = math.sqrt(fitted_sq / inl.shape[0])
    nominal_rms = math.sqrt(nominal_sq / inl.shape[0])
    return (1 if nominal_rms < 1.5 * fitted_rms + 0.005 else 2), normal, centre, len(inl)


def fit_floor(points: np.ndarray, cam: np.ndarray, *, band_m: float = 0.6,
              inlier_m: float = 0.02, max_tilt_deg: float = 25.0, hypotheses: int = 96,
              min_inliers: int = 60, min_share: float = 0.15, max_offset_m: float = 0.2,
              seed: int = 0) -> FloorFit:  # fmt: skip
    """RANSAC plane of the points near the nominal floor; ``NOMINAL`` if none is good."""
    cam = np.ascontiguousarray(cam, np.float64)
    kind, normal, centre, inliers = _ransac(
        np.ascontiguousarray(points, np.float64), cam, band_m, inlier_m,
        math.cos(math.radians(max_tilt_deg)), hypotheses, min_inliers, min_share,
        max_offset_m, SCORE_POINTS, seed,
    )  # fmt: skip
    if kind == 0:
        return NOMINAL
    if kind == 1:
        return FloorFit(np.eye(3), 0.0, 0.0, inliers, False)
    rot = _rotation_between(normal, np.array([0.0, 0.0, 1.0]))
    # Heights measured from the camera: the plane, turned about it, lies at this z.
    floor_z = float(cam[2] + normal @ (centre - cam))
    tilt = math.degrees(math.acos(min(1.0, float(normal[2]))))
    return FloorFit(rot, floor_z, tilt, inliers, True)
