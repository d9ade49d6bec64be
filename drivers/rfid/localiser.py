"""Reads → position, heading and a quality figure.

Chen et al.'s method (``method="centroid"``): the median of the last n RSSI reads of each
UHF tag, ranged with the log-distance model; the three nearest tags; each pair of range
circles gives the intersection point nearer the third circle; the position is the
centroid of those three points. ``method="lsq"`` refines that estimate by weighted
least squares over the nearest ``lsq_tags`` tags (Gauss-Newton). A floor (LF) read
overrides both: one tag → its position, two → their midpoint, three or more → their
centroid; for ``lf_hold_s`` after the last floor read (the gap between two tags of the
lattice) that fix is carried on at the speed of the last fixes. Heading comes from
successive positions.
"""

from __future__ import annotations

import math
from collections import deque
from dataclasses import dataclass

import numpy as np

from .protocol import Read
from .rssi import A_DB, N_PATH, distance_from_rssi
from .tags import TagMap

METHODS = ("lsq", "centroid")
DEFAULT_METHOD = "lsq"
"""The more accurate of the two in ``guidebelt rfid-eval``, measured on the simulated courtyard."""

QUALITY_SCALE_M = 0.25
"""Position spread at which the quality figure is 0.5."""


@dataclass(frozen=True)
class Estimate:
    x: float
    y: float
    heading: float
    quality: float
    source: str  # "lf", "lf-hold" or "uhf"
    n_tags: int
    t: float


def _circle_point(c1, r1, c2, r2, c3, r3) -> np.ndarray:
    """The point the circles (c1, r1) and (c2, r2) share that lies nearest circle 3.

    Noisy ranges often miss each other: circles too far apart give the point dividing
    the gap between them, nested circles the point halfway between their near sides.
    """
    v = c2 - c1
    dist = float(np.hypot(*v))
    if dist < 1e-9:
        return (c1 + c2) / 2
    u = v / dist
    if dist >= r1 + r2:  # apart
        return c1 + u * (r1 + (dist - r1 - r2) / 2)
    if dist <= abs(r1 - r2):  # one inside the other
        s = 1.0 if r1 >= r2 else -1.0
        return (c1 + s * u * r1 + c2 + s * u * r2) / 2
    a = (r1 * r1 - r2 * r2 + dist * dist) / (2 * dist)
    h = math.sqrt(max(r1 * r1 - a * a, 0.0))
    base = c1 + u * a
    perp = np.array([-u[1], u[0]])
    p, q = base + h * perp, base - h * perp
    miss_p = abs(float(np.hypot(*(p - c3))) - r3)
    miss_q = abs(float(np.hypot(*(q - c3))) - r3)
    return p if miss_p <= miss_q else q


def triangle_centroid(centres: np.ndarray, d: np.ndarray) -> np.ndarray:
    """The paper's trilateration from exactly three tags: centres (3, 2), ranges (3,)."""
    pts = [
        _circle_point(centres[i], d[i], centres[j], d[j], centres[k], d[k])
        for i, j, k in ((0, 1, 2), (1, 2, 0), (2, 0, 1))
    ]
    return np.mean(pts, axis=0)


def least_squares(
    centres: np.ndarray, d: np.ndarray, x0: np.ndarray, iters: int = 20
) -> np.ndarray:
    """Minimise Σ wᵢ (|p − cᵢ| − dᵢ)² from ``x0``, wᵢ = 1/dᵢ² (ranging error grows with d)."""
    w = 1.0 / np.maximum(d, 0.1) ** 2
    p = np.array(x0, dtype=float)
    for _ in range(iters):
        diff = p - centres
        r = np.maximum(np.hypot(diff[:, 0], diff[:, 1]), 1e-6)
        jac = diff / r[:, None]
        jw = jac * w[:, None]
        hess = jac.T @ jw + 1e-6 * np.eye(2)  # damping keeps collinear tags solvable
        step = np.linalg.solve(hess, jw.T @ (r - d))
        p -= step
        if float(np.hypot(*step)) < 1e-5:
            break
    return p


def position_spread(p: np.ndarray, centres: np.ndarray, d: np.ndarray, sigma_db: np.ndarray):
    """Expected position error (m): range errors through the tags' geometry, plus misfit."""
    diff = p - centres
    r = np.maximum(np.hypot(diff[:, 0], diff[:, 1]), 1e-6)
    jac = diff / r[:, None]
    sigma_d = np.maximum(d, 0.1) * math.log(10) / (10 * N_PATH) * sigma_db
    info = (jac / sigma_d[:, None] ** 2).T @ jac + 1e-9 * np.eye(2)
    cov_trace = float(np.trace(np.linalg.inv(info)))
    misfit = float(np.sqrt(np.mean((r - d) ** 2)))
    return math.sqrt(max(cov_trace, 0.0) + misfit * misfit)


class Localiser:
    """Keeps the latest reads per tag and estimates the pose on demand."""

    def __init__(
        self,
        tag_map: TagMap,
        *,
        method: str = DEFAULT_METHOD,
        n_reads: int = 5,
        window_s: float = 0.5,
        lf_window_s: float = 0.05,
        lf_hold_s: float = 0.3,
        lsq_tags: int = 8,
        heading_window_s: float = 1.0,
        heading_min_m: float = 0.15,
        a: float = A_DB,
        n: float = N_PATH,
    ) -> None:
        if method not in METHODS:
            raise ValueError(f"unknown method {method!r}; choose one of {METHODS}")
        self.tags = tag_map
        self.method = method
        self.n_reads = n_reads
        self.window_s = window_s
        self.lf_window_s = lf_window_s
        self.lf_hold_s = lf_hold_s
        self.lsq_tags = max(3, lsq_tags)
        self.heading_window_s = heading_window_s
        self.heading_min_m = heading_min_m
        self.a, self.n = a, n
        self._uhf: dict[int, deque[tuple[float, float]]] = {}
        self._lf_round: list[int] = []
        self._lf_round_t = -math.inf
        self._track: deque[tuple[float, float, float]] = deque()
        self._lf_fixes: deque[tuple[float, float, float, int]] = deque(maxlen=64)
        """(t, x, y, tags) of each LF round; the last one grows while its round lasts."""
        self.heading = math.pi / 2  # until the user has moved: facing north

    def add(self, read: Read) -> None:
        """Take one read of a known tag (the ReadFilter has already dropped the rest)."""
        i = self.tags.uhf_index.get(read.tag_id)
        if i is not None:
            self._uhf.setdefault(i, deque(maxlen=self.n_reads)).append((read.t, read.rssi))
            return
        j = self.tags.lf_index.get(read.tag_id)
        if j is not None:
            self._add_lf(read.t, j)

    def _add_lf(self, t: float, j: int) -> None:
        """Group LF reads by round: only the latest round counts (older tags lie behind)."""
        if abs(t - self._lf_round_t) <= 5e-3:  # rounds are 20 ms apart
            if j not in self._lf_round:
                self._lf_round.append(j)
        elif t > self._lf_round_t:
            self._lf_round, self._lf_round_t = [j], t
        else:
            return  # a late read from an older round
        x, y = self.tags.lf_xy[self._lf_round].mean(axis=0)
        fix = (self._lf_round_t, float(x), float(y), len(self._lf_round))
        if self._lf_fixes and self._lf_fixes[-1][0] == self._lf_round_t:
            self._lf_fixes[-1] = fix
        else:
            self._lf_fixes.append(fix)

    def _lf_fix(self, now: float) -> tuple[np.ndarray, int] | None:
        if not self._lf_fixes or now - self._lf_fixes[-1][0] > self.lf_window_s:
            return None
        _, x, y, k = self._lf_fixes[-1]
        return np.array([x, y]), k

    def _lf_held(self, now: float) -> tuple[np.ndarray, float] | None:
        """Just past a floor tag: its fix carried on at the speed the last fixes show.

        Between two tags of the lattice a walking user is out of LF range for a moment;
        dead reckoning from the last fixes beats falling back to UHF ranging for that.
        """
        if not self._lf_fixes or now - self._lf_fixes[-1][0] > self.lf_hold_s:
            return None
        t1, x1, y1, _ = self._lf_fixes[-1]
        first = next((f for f in self._lf_fixes if f[0] >= t1 - 1.0), self._lf_fixes[-1])
        t0, x0, y0, _ = first
        vx, vy = ((x1 - x0) / (t1 - t0), (y1 - y0) / (t1 - t0)) if t1 - t0 >= 0.2 else (0, 0)
        age = now - t1
        return np.array([x1 + vx * age, y1 + vy * age]), 1.0 - 0.5 * age / self.lf_hold_s

    def _ranges(self, now: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Tag indices, median ranges and the RSSI spread (dB) of the median, nearest first."""
        idx, med, spread = [], [], []
        for i, reads in self._uhf.items():
            rssi = [r for t, r in reads if t >= now - self.window_s]
            if not rssi:
                continue
            m = float(np.median(rssi))
            mad = float(np.median(np.abs(np.asarray(rssi) - m))) * 1.4826
            idx.append(i)
            med.append(m)
            spread.append(max(mad, 1.0) / math.sqrt(len(rssi)))
        d = distance_from_rssi(np.array(med), self.a, self.n)
        order = np.argsort(d, kind="stable")
        return np.array(idx, dtype=int)[order], d[order], np.array(spread)[order]

    def _uhf_fix(self, now: float) -> tuple[np.ndarray, float, int] | None:
        idx, d, spread = self._ranges(now)
        if len(idx) < 3:
            return None
        centres = self.tags.uhf_xy[idx]
        p = triangle_centroid(centres[:3], d[:3])
        k = 3
        if self.method == "lsq":
            k = min(self.lsq_tags, len(idx))
            p = least_squares(centres[:k], d[:k], p)
        sigma = position_spread(p, centres[:k], d[:k], spread[:k])
        p = np.clip(p, [0.0, 0.0], [self.tags.width_m, self.tags.height_m])
        return p, QUALITY_SCALE_M / (QUALITY_SCALE_M + sigma), k

    def estimate(self, now: float) -> Estimate | None:
        """The pose at ``now`` from the reads in the windows; None when too few tags answer."""
        lf = self._lf_fix(now)
        held = self._lf_held(now) if lf is None else None
        if lf is not None:
            p, k = lf
            quality, source = 1.0, "lf"
        elif held is not None:
            p, quality = held
            k, source = 0, "lf-hold"
        else:
            fix = self._uhf_fix(now)
            if fix is None:
                return None
            p, quality, k = fix
            source = "uhf"
        x, y = float(p[0]), float(p[1])
        self._update_heading(now, x, y)
        return Estimate(x, y, self.heading, float(quality), source, k, now)

    def _update_heading(self, now: float, x: float, y: float) -> None:
        self._track.append((now, x, y))
        while self._track and self._track[0][0] < now - self.heading_window_s:
            self._track.popleft()
        _, x0, y0 = self._track[0]
        if math.hypot(x - x0, y - y0) >= self.heading_min_m:
            self.heading = math.atan2(y - y0, x - x0)
