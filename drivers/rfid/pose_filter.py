"""A pose that is always there: an extended Kalman filter over RFID, LF signposts and steps.

Chen et al. localise from RFID alone: the median RSSI of the three nearest UHF tags ranged
with ``d = 10^((|RSSI| − A)/(10 n))`` (eq. 1), their triangle centroid (eq. 2), LF floor
tags at each intersection as signposts ("within 10 cm"), and the heading from successive
positions (eq. 3). With the paper's ~1.5 m UHF field and tags only on the obstacles'
feature points, three tags answer almost nowhere, so that method leaves the user without a
position most of the time. This filter keeps one:

- state ``[x, y, b, k]``: position (m), the compass's bias b (rad) — indoors a compass is
  off by a slowly varying amount (steel, wiring) — and the stride-scale error k of the
  pedometer's stride model; the fixes make both observable;
- predict on each step the pedometer reports: ``p += L (1 + k) (cos(c − b), sin(c − b))``
  with the measured step length L and the compass reading c;
- update with every UHF tag read since the last update — one range per tag through eq. 1
  (in dB, where its noise is Gaussian), so one or two tags in reach still pull the estimate,
  where trilateration needs three;
- update with an LF read: the paper's signpost (one tag, the midpoint of two, the centroid of
  three), to within the LF read range;
- heading: the compass less the estimated bias (it follows a turn on the spot at once), and
  eq. 3 over the filtered track, fused as a measurement of the bias while the user walks
  straight.

numpy rather than ``filterpy``: four states, a scalar update per tag read and a nonlinear
motion model; the library's ``ExtendedKalmanFilter`` would add a dependency and still need
every Jacobian written here, and its per-update object churn is slower at 20 Hz per user.

The pose carries ``sigma_m``, the 1-σ position uncertainty (the larger principal axis of the
position covariance), and the wire's ``quality`` derived from it (``protocol.pose_quality``).
"""

from __future__ import annotations

import math
from collections import deque
from dataclasses import dataclass

import numpy as np

from protocol.pose_quality import quality_from_sigma

from .filter_params import FilterParams
from .map_match import Likelihood, grid_measurement
from .protocol import Read
from .rssi import A_DB, N_PATH, NEAR_FIELD_M
from .tags import TagMap

LN10 = math.log(10.0)
N_STATE = 4
"""x, y (m), the compass bias b (rad) and the stride-scale error k (fraction)."""
STRIDE_TURN_RAD = math.radians(60.0)
"""Turned this far since the last step: the user is turning on the spot, not striding on
(walking round a corner turns the compass less within one stride)."""
LF_ROUND_S = 5e-3
"""Reads of one LF round share its time within this (rounds are 20 ms apart)."""


@dataclass(frozen=True)
class FilteredPose:
    x: float
    y: float
    heading: float
    """Compass less the estimated bias (rad, 0 = east, CCW)."""
    heading_eq3: float | None
    """Eq. 3 over the filtered track (None until the user has walked far enough)."""
    sigma_m: float
    quality: float
    t: float
    source: str
    """What last corrected it: ``lf``, ``uhf`` or ``steps`` (dead reckoning only)."""


class PoseFilter:
    """One user's pose; feed it ``step``, ``compass``, ``uhf`` and ``lf``, ask ``pose``."""

    def __init__(
        self,
        tag_map: TagMap,
        params: FilterParams | None = None,
        *,
        start: tuple[float, float] | None = None,
        start_sigma_m: float = 0.3,
        pedometer: bool = False,
        a: float = A_DB,
        n: float = N_PATH,
    ) -> None:
        """``start``: where the user is known to begin (an entrance), if anywhere.
        ``pedometer``: steps will be reported, so no step means standing still; without one
        the position's spread grows with time (``drift_mps``) until the next fix."""
        self.tags = tag_map
        self.p = params or FilterParams()
        self.a, self.n = a, n
        self.s = np.zeros(N_STATE)
        self.P = np.diag([1.0, 1.0, self.p.init_bias_sigma_rad**2, self.p.init_scale_sd**2])
        self.ready = False
        if start is not None:
            self.s[:2] = start
            self.P[0, 0] = self.P[1, 1] = start_sigma_m**2
            self.ready = True
        self.compass_rad: float | None = None
        self.source = "steps"
        self.t = 0.0
        self._uhf: dict[int, list[float]] = {}
        self._tag_updates: dict[int, deque[float]] = {}
        self._lf_updates: dict[tuple[float, float], deque[float]] = {}
        self._track: deque[tuple[float, float, float, float]] = deque()
        """(t, x, y, compass) after each step, for eq. 3."""
        self.heading_eq3: float | None = None
        self.pedometer = pedometer
        """Motion comes from steps, not from the drift model (set by the first step too)."""
        self._last_t: float | None = None
        self._step_t: float | None = None
        self._still = False
        self._step_dt = 0.5
        self._cadence = False
        self._step_compass = 0.0
        self._step_len = 0.0
        self._lf_round: list[int] = []
        self._lf_round_t = -math.inf
        self._lf_done_t = -math.inf

    def add(self, read: Read) -> None:
        """One read of a known tag, as the reader's ``ReadFilter`` passes it on."""
        if read.tag_id in self.tags.uhf_index:
            self.uhf(read.t, read.tag_id, read.rssi)
            return
        j = self.tags.lf_index.get(read.tag_id)
        if j is None or abs(read.t - self._lf_done_t) <= LF_ROUND_S:
            return  # unknown, or a straggler of a round already used
        if abs(read.t - self._lf_round_t) <= LF_ROUND_S:
            if j not in self._lf_round:
                self._lf_round.append(j)
            return
        self._flush_lf()
        self._lf_round, self._lf_round_t = [j], read.t

    def _flush_lf(self) -> None:
        """The paper's signpost from one LF round: one tag, the midpoint of two, the centroid."""
        if not self._lf_round:
            return
        xy = self.tags.lf_xy[self._lf_round].mean(axis=0)
        self.lf(self._lf_round_t, (float(xy[0]), float(xy[1])), len(self._lf_round))
        self._lf_done_t = self._lf_round_t
        self._lf_round = []

    # -- inputs ---------------------------------------------------------------------------

    def compass(self, t: float, heading_rad: float) -> None:
        self.compass_rad = heading_rad
        self.t = max(self.t, t)

    def step(self, t: float, length_m: float, compass_rad: float) -> None:
        """The pedometer counted a step of ``length_m`` with the compass reading ``compass_rad``."""
        self.compass(t, compass_rad)
        self.pedometer = True
        if self._step_t is not None and 0.2 <= t - self._step_t <= 2.0:
            self._step_dt = t - self._step_t
            self._cadence = True
        else:
            self._cadence = False  # the first step after a stop: no stride to carry on
        self._step_t, self._step_len, self._step_compass = t, length_m, compass_rad
        self._still = False
        if not self.ready:
            return
        th = compass_rad - self.s[2]
        c, s = math.cos(th), math.sin(th)
        stride = length_m * (1.0 + self.s[3])  # the pedometer's stride model, corrected
        self.s[0] += stride * c
        self.s[1] += stride * s
        f = np.eye(N_STATE)
        f[0, 2] = stride * s
        f[1, 2] = -stride * c
        f[0, 3] = length_m * c
        f[1, 3] = length_m * s
        sl = self.p.step_sigma_m + self.p.step_sigma_frac * length_m
        sh = length_m * self.p.heading_sigma_rad
        rot = np.array([[c, -s], [s, c]])
        q = np.zeros((N_STATE, N_STATE))
        q[:2, :2] = rot @ np.diag([sl * sl, sh * sh]) @ rot.T
        q[2, 2] = self.p.bias_walk_rad**2
        self.P = f @ self.P @ f.T + q
        self._eq3(t, compass_rad)

    def still(self, t: float) -> None:
        """The IMU felt no stride since the last step (the user stood, turned on the spot or
        bumped): no stride is under way until the next step. Without it the belt walks'
        pose ran a whole stride ahead of a user who had stopped, onto the goal: ARRIVED
        0.5-0.6 m from it (4 of 300 walks)."""
        self.t = max(self.t, t)
        self._still = True

    def bump(self, t: float) -> None:
        """The user walked into something the map said was clear of the pose: the pose is
        wrong by more than its margin, so it is made that much less sure (the daemon widens
        the margin by a = 2σ and the route moves off the obstacle)."""
        self.t = max(self.t, t)
        if self.ready:
            self.P[0, 0] += self.p.bump_sigma_m**2
            self.P[1, 1] += self.p.bump_sigma_m**2

    def constrain(self, t: float, like: Likelihood) -> bool:
        """A measurement of the position against the map (``map_match``: a bump, the
        camera's nearest obstacle), made linear over the ±3σ ellipse. True if it counted."""
        self.t = max(self.t, t)
        if not self.ready:
            return False
        here = self.s[:2] + self._stride(t)
        got = grid_measurement(here, self.P[:2, :2], like)
        if got is None:
            return False
        rows, z, r = got
        h = np.zeros((rows.shape[0], N_STATE))
        h[:, :2] = rows
        self._update(z - rows @ here, h, r)
        return True

    def uhf(self, t: float, tag_id: str, rssi_dbm: float) -> None:
        """A UHF read; it is used at the next ``pose`` (all reads of a tag since, by median)."""
        i = self.tags.uhf_index.get(tag_id)
        if i is not None:
            self._uhf.setdefault(i, []).append(abs(rssi_dbm))
            self.t = max(self.t, t)

    def lf(self, t: float, xy: tuple[float, float], n_tags: int) -> None:
        """An LF round: the paper's signpost position from the ``n_tags`` read together."""
        self.t = max(self.t, t)
        z = np.asarray(xy, dtype=float)
        if not self.ready:
            self._init_at(z, self.p.lf_sigma_m)
            self.source = "lf"
            return
        # Where the user stands within a tag's 10 cm is the same in every round of a user
        # standing there: the m-th round of one signpost within tag_memory_s gets the
        # variance m(m − 1) σ², so that all of them together count at most twice
        # (Σ 1/(m(m − 1)) < 1). At 50 rounds a second, standing still drove σ to 6 mm,
        # and the stride scale and compass bias went wrong on it (0.46 m off at σ 0.09 m).
        key = (round(float(z[0]), 2), round(float(z[1]), 2))
        seen = self._lf_updates.setdefault(key, deque())
        while seen and seen[0] < t - self.p.tag_memory_s:
            seen.popleft()
        seen.append(t)
        m = len(seen)
        r = max(1, m * (m - 1)) * (self.p.lf_sigma_m / math.sqrt(n_tags)) ** 2 * np.eye(2)
        h = np.zeros((2, N_STATE))
        h[0, 0] = h[1, 1] = 1.0
        self._update(z - self.s[:2] - self._stride(t), h, r)
        self.source = "lf"

    # -- output ---------------------------------------------------------------------------

    def pose(self, now: float) -> FilteredPose | None:
        """Fold in the UHF reads gathered since the last call; None before any position."""
        self.t = max(self.t, now)
        if not self.pedometer and self.ready and self._last_t is not None:
            dt = max(0.0, now - self._last_t)
            self.P[0, 0] += self.p.drift_mps**2 * dt
            self.P[1, 1] += self.p.drift_mps**2 * dt
        self._last_t = now
        if self._lf_round and now - self._lf_round_t > LF_ROUND_S:
            self._flush_lf()
        self._fold_uhf()
        if not self.ready:
            return None
        sigma = self.sigma_m
        x, y = self.s[:2] + self._stride(now)
        return FilteredPose(
            float(x), float(y), self.heading, self.heading_eq3, sigma,
            quality_from_sigma(sigma), now, self.source,
        )  # fmt: skip

    def _stride(self, now: float) -> np.ndarray:
        """Where the user is in the stride under way, from the last step's end.

        Between two steps a walking user is not standing at the last one: the pose and every
        fix taken mid-stride are put at the cadence of the last steps (never past one more
        step). The state itself moves only by the steps reported, so a step that never comes
        (the user stopped) leaves nothing behind.
        """
        if (
            not self._cadence
            or self._still
            or self._step_t is None
            or now - self._step_t >= 1.5 * self._step_dt
            or self.compass_rad is None
            or abs(_wrap(self.compass_rad - self._step_compass)) > STRIDE_TURN_RAD
        ):
            return np.zeros(2)  # not walking steadily, or turned since: no stride under way
        ahead = min(1.0, (now - self._step_t) / self._step_dt) * self._step_len * (1.0 + self.s[3])
        th = self.heading
        return np.array([ahead * math.cos(th), ahead * math.sin(th)])

    @property
    def sigma_m(self) -> float:
        return math.sqrt(max(float(np.linalg.eigvalsh(self.P[:2, :2])[-1]), 0.0))

    @property
    def heading(self) -> float:
        """The compass less its bias; before any compass reading, eq. 3 or north."""
        if self.compass_rad is not None:
            return _wrap(self.compass_rad - float(self.s[2]))
        return self.heading_eq3 if self.heading_eq3 is not None else math.pi / 2

    # -- inside ---------------------------------------------------------------------------

    def _init_at(self, xy: np.ndarray, sigma: float) -> None:
        self.s[:2] = xy
        self.P[:2, :] = 0.0
        self.P[:, :2] = 0.0
        self.P[0, 0] = self.P[1, 1] = sigma * sigma
        self.ready = True

    def _fold_uhf(self) -> None:
        reads, self._uhf = self._uhf, {}
        if not reads:
            return
        if not self.ready:  # the strongest tag: the user is within its field
            i = max(reads, key=lambda k: -float(np.median(reads[k])))
            self._init_at(self.tags.uhf_xy[i], self.p.init_sigma_m)
        used = False
        for i, vals in sorted(reads.items(), key=lambda kv: float(np.median(kv[1]))):
            seen = self._tag_updates.setdefault(i, deque())
            while seen and seen[0] < self.t - self.p.tag_memory_s:
                seen.popleft()
            m = len(seen) + 1
            z = float(np.median(vals))
            if self._range_update(self.tags.uhf_xy[i], z, len(vals), m):
                seen.append(self.t)
                used = True
        if used:
            self.source = "uhf"

    def _range_update(self, centre: np.ndarray, z_db: float, k: int, m: int = 1) -> bool:
        """Eq. 1 read backwards: |RSSI| = A + 10 n log10 r, updated in dB."""
        diff = self.s[:2] + self._stride(self.t) - centre
        r = max(float(np.hypot(*diff)), NEAR_FIELD_M)
        pred = self.a + 10.0 * self.n * math.log10(r)
        h = np.zeros((1, N_STATE))
        h[0, :2] = 10.0 * self.n / (LN10 * r * r) * diff
        var = self.p.sigma_read_db**2 / k + self.p.sigma_tag_db**2 * m
        # Near a tag the log-range bends sharply over the position's spread: the
        # second-order term ½ tr((∇²h P)²) the linear update leaves out, added as noise.
        curv = 10.0 * self.n / LN10 / (r * r)
        pos = self.P[:2, :2]
        var += 0.5 * curv * curv * float(np.trace(pos @ pos))
        innov = np.array([z_db - pred])
        s = float((h @ self.P @ h.T)[0, 0]) + var
        if innov[0] ** 2 > self.p.gate_sigma**2 * s:
            return False
        self._update(innov, h, np.array([[var]]))
        return True

    def _update(self, innov: np.ndarray, h: np.ndarray, r: np.ndarray) -> None:
        s = h @ self.P @ h.T + r
        gain = self.P @ h.T @ np.linalg.inv(s)
        self.s = self.s + gain @ innov
        self.s[2] = _wrap(float(self.s[2]))
        ikh = np.eye(N_STATE) - gain @ h
        self.P = ikh @ self.P @ ikh.T + gain @ r @ gain.T  # Joseph form: stays symmetric PSD

    def _eq3(self, t: float, compass_rad: float) -> None:
        """Eq. 3 over the filtered track; while walking straight it measures the bias."""
        x, y = float(self.s[0]), float(self.s[1])
        self._track.append((t, x, y, compass_rad))
        while self._track and self._track[0][0] < t - self.p.eq3_window_s:
            self._track.popleft()
        _, x0, y0, _ = self._track[0]
        dist = math.hypot(x - x0, y - y0)
        if dist < self.p.eq3_min_m:
            return
        theta = math.atan2(y - y0, x - x0)  # eq. 3
        self.heading_eq3 = theta
        turns = [_wrap(c - compass_rad) for *_, c in self._track]
        if max(abs(a) for a in turns) > self.p.eq3_max_turn_rad:
            return
        mean_c = compass_rad + float(np.mean(turns))
        # The track is the filter's own, so the measurement is weak: only what the
        # positions' spread over ``dist`` allows, and never stronger than eq3_gain_sigma.
        sig = max(self.p.eq3_gain_sigma_rad, math.atan2(self.sigma_m, dist))
        h = np.zeros((1, N_STATE))
        h[0, 2] = 1.0
        innov = np.array([_wrap(mean_c - theta - float(self.s[2]))])
        self._update(innov, h, np.array([[sig * sig]]))


def _wrap(a: float) -> float:
    return (a + math.pi) % (2.0 * math.pi) - math.pi
