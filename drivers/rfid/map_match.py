"""What the map says about the pose: a bump and the camera's nearest obstacle as measurements.

The RFID pose filter's fixes come from tags; between them the pose drifts, and near an
obstacle the camera mapped a 0.3–0.5 m error is a collision. But the user's own obstacle
sensing carries position too, once it is compared with the map the daemon holds:

- **contact**: the user bumped into something while stepping along the compass heading, so
  an occupied cell lies within one step ahead of where the user truly is;
- **the camera's nearest obstacle** (``nearest_m`` at ``bearing`` from the heading, as the
  mapper's proximity reports it): the point it names is on an occupied cell. This is the
  likelihood-field model of Thrun, Burgard & Fox, *Probabilistic Robotics* §6.4:
  p(z | x) = z_hit · N(d; 0, σ_hit) + z_rand, d the distance from the measured end point to
  the nearest occupied cell.

Neither is Gaussian in the position (a wall ahead says "somewhere along this line"), so the
update is done on a grid of positions over the filter's ±3σ ellipse: the Gaussian prior
times the likelihood, whose mean and covariance are then handed back to the Kalman filter
as the equivalent linear measurement (``grid_measurement``). The map is the daemon's
occupancy grid (row 0 north, metres from the south-west corner), OCCUPIED = 1.
"""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np

OCCUPIED = 1
GRID = 17
"""Positions per axis of the grid over the ±3σ ellipse."""
HIT_SIGMA_M = 0.10
"""End-point error: a cell's width plus a few degrees of heading at a metre."""
MIN_SIGMA_M = HIT_SIGMA_M
"""The most a map match may say along any direction (1 σ)."""
Z_RAND = 0.1
"""The map may be wrong or out of date (a person, a blob not yet mapped): never zero."""
KEEP_FRACTION = 1e-3
"""A direction whose information is under this fraction of the prior's says nothing. At 5 %
the camera's weak, repeated pulls were dropped and the walks bumped again (20 % clutter,
seeds 4, 9, 10, 21 of 50; 40 %: 3, 13, 36): they add up."""
Z_CONTACT = 0.01
"""A bump is sure to have happened; only the map may lack what was hit (the camera looks
where the user steps, so rarely). With the camera's floor a bump left a two-humped
posterior whose spread grew, and the moment-matched measurement said nothing."""
Z_OFF_FREE = 0.02
"""How likely the user stands on a cell the map holds occupied (a blob mapped wide)."""
CONTACT_RAYS_RAD = (-0.5, -0.25, 0.0, 0.25, 0.5)
"""A step goes up to ±40° off the body's heading (the walker turns in place beyond)."""

Likelihood = Callable[[np.ndarray], np.ndarray]
"""Positions (n, 2) in metres → likelihoods (n,)."""


def _cells(occupancy: np.ndarray, cell_m: float, xy: np.ndarray) -> tuple[np.ndarray, ...]:
    h, w = occupancy.shape
    rows = h - 1 - np.floor(xy[..., 1] / cell_m).astype(np.int64)
    cols = np.floor(xy[..., 0] / cell_m).astype(np.int64)
    inside = (rows >= 0) & (rows < h) & (cols >= 0) & (cols < w)
    return np.clip(rows, 0, h - 1), np.clip(cols, 0, w - 1), inside


def contact_likelihood(
    occupancy: np.ndarray, cell_m: float, heading: float, reach_m: float
) -> Likelihood:
    """A bump: from the position, a step of up to ``reach_m`` along the heading (± a
    step's spread) meets an occupied cell or the map's edge."""
    s = np.linspace(0.0, reach_m, max(2, math.ceil(reach_m / (0.25 * cell_m))))
    dirs = np.array([[math.cos(heading + a), math.sin(heading + a)] for a in CONTACT_RAYS_RAD])
    ray = s[None, :, None] * dirs[:, None, :]  # (rays, samples, 2)

    stand = free_space_likelihood(occupancy, cell_m)

    def like(pts: np.ndarray) -> np.ndarray:
        xy = pts[:, None, None, :] + ray[None]
        rows, cols, inside = _cells(occupancy, cell_m, xy)
        # The map's edge is no hit: the courtyard's outer walls are on the map, and counting
        # beyond them drew an estimate by a wall out through it (σ 0.6 m: the ±3σ grid
        # reached past the edge, where every step "hit"; 40 %, seed 19 bumped 34 times).
        hit = (occupancy[rows, cols] == OCCUPIED) & inside
        return np.where(hit.any(axis=(1, 2)), 1.0, Z_CONTACT) * stand(pts)

    return like


def free_space_likelihood(occupancy: np.ndarray, cell_m: float) -> Likelihood:
    """The user stands on a free cell of the map: never inside an obstacle or off the map.

    Only ``Z_OFF_FREE`` there, not 0: a blob mapped a cell too wide must not make the
    true position impossible."""

    def like(pts: np.ndarray) -> np.ndarray:
        rows, cols, inside = _cells(occupancy, cell_m, pts)
        free = inside & (occupancy[rows, cols] != OCCUPIED)
        return np.where(free, 1.0, Z_OFF_FREE)

    return like


def obstacle_likelihood(
    occupancy: np.ndarray, cell_m: float, heading: float, nearest_m: float, bearing: float
) -> Likelihood:
    """The camera's nearest obstacle edge ``nearest_m`` away at ``bearing`` (radians from
    the heading, left positive): its end point lies on an occupied cell's edge."""
    rr, cc = np.nonzero(occupancy == OCCUPIED)
    h = occupancy.shape[0]
    centres = np.column_stack([(cc + 0.5) * cell_m, (h - rr - 0.5) * cell_m])
    way = heading + bearing
    end = np.array([math.cos(way), math.sin(way)]) * nearest_m

    def like(pts: np.ndarray) -> np.ndarray:
        ends = pts + end
        lo, hi = ends.min(axis=0) - 3 * cell_m, ends.max(axis=0) + 3 * cell_m
        near = centres[np.all((centres >= lo) & (centres <= hi), axis=1)]
        if near.size == 0:
            return np.full(len(pts), Z_RAND)
        d = np.sqrt(((ends[:, None, :] - near[None]) ** 2).sum(axis=2)).min(axis=1)
        d = np.maximum(d - cell_m / 2, 0.0)  # to the cell's edge, where the camera sees it
        return np.exp(-0.5 * (d / HIT_SIGMA_M) ** 2) + Z_RAND

    return like


def _moments(pts: np.ndarray, w: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    w = w / w.sum()
    m = w @ pts
    diff = pts - m
    return m, (diff * w[:, None]).T @ diff


def grid_measurement(
    mean: np.ndarray, cov: np.ndarray, like: Likelihood
) -> tuple[np.ndarray, np.ndarray, np.ndarray] | None:
    """The linear measurement of the position equivalent to ``like``: (H rows over x, y;
    z; R), so that a Kalman update with it gives the grid posterior's mean and covariance.
    None when the likelihood says next to nothing (``KEEP_FRACTION`` of the prior's
    information along every direction: flat over the ellipse).

    Posterior information = prior's + the measurement's, so the measurement's information
    is inv(C_post) − inv(P), kept along the directions where it is positive; z follows
    from inv(C_post) m_post = inv(P) m + info · z.
    """
    vals, vecs = np.linalg.eigh(cov)
    scale = vecs * np.sqrt(np.maximum(vals, 1e-8))
    u = np.linspace(-3.0, 3.0, GRID)
    uu = np.stack(np.meshgrid(u, u), axis=-1).reshape(-1, 2)
    pts = mean + uu @ scale.T
    prior = np.exp(-0.5 * (uu**2).sum(axis=1))
    m0, c0 = _moments(pts, prior)
    w = prior * like(pts)
    if float(w.sum()) <= 0.0:
        return None
    m, c = _moments(pts, w)
    # Against the grid's own prior, not P: the ±3σ cut and the spacing bias both alike.
    p_inv, c_inv = np.linalg.inv(c0), np.linalg.inv(c)
    mean = m0
    l_vals, l_vecs = np.linalg.eigh(c_inv - p_inv)
    keep = l_vals > KEEP_FRACTION * float(np.linalg.eigvalsh(p_inv)[-1])
    if not keep.any():
        return None
    v, lam = l_vecs[:, keep], l_vals[keep]
    b = c_inv @ m - p_inv @ mean
    z = (v.T @ b) / lam
    # One end point against a map of 10 cm cells says no more than HIT_SIGMA_M: a sharper
    # grid posterior is the grid's own doing, and taken at its word it drove σ to 6 mm and
    # the stride scale and compass bias off with it (a 0.46 m error at σ 0.09 m, 21 bumps).
    return v.T, z, np.diag(np.maximum(1.0 / lam, MIN_SIGMA_M**2))
