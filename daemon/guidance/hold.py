"""Hold instead of detour.

Hong & DeSouza saw their wheelchair go sideways or backwards whenever a moving obstacle crossed
the path far ahead: the planner, seeing the way blocked, sent it round the other side. A person
walking would simply wait a moment. So when a replanned path would turn the user around, and the
reason is a block far ahead on the path followed until a moment ago, guidance says "wait" and
holds for a few seconds; if the way clears the walk goes on, otherwise the detour is taken.

The guidance sees only the inflated ``blocked`` map, so a dead end revealed far ahead looks the
same as a person stepping across the path: both earn one short hold, never more than one per
blockage.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numba import njit


@dataclass
class HoldPolicy:
    hold_s: float = 4.0
    """How long to wait for the way to clear before taking the detour; 0 turns holding off."""
    far_m: float = 1.5
    """Only a block at least this far along the old path earns a hold; a near one is a wall."""
    recent_s: float = 2.0
    """The old path must have been clear this recently: the block is new."""
    turn_deg: float = 100.0
    """A new path leaving the user this far from the old path's direction 'turns the user
    around' (both directions are taken over the first ``ahead_m`` of each path)."""
    ahead_m: float = 1.0

    def __post_init__(self) -> None:
        self._clear_path: np.ndarray | None = None
        self._clear_at = -math.inf
        self.holding_until: float | None = None
        self._spent = False
        self.holds = 0
        """Holds started so far (for tests and walk statistics)."""

    def reset(self) -> None:
        self.__post_init__()

    def turns_around(self, path: np.ndarray, user_rc: np.ndarray, cell_m: float) -> bool:
        """Does ``path`` leave the user the opposite way from the last clear path?"""
        if self._clear_path is None:
            return False
        new = _direction(path, user_rc, self.ahead_m / cell_m)
        old = _direction(self._clear_path, user_rc, self.ahead_m / cell_m)
        if new is None or old is None:
            return False
        diff = abs((new - old + math.pi) % (2 * math.pi) - math.pi)
        return diff > math.radians(self.turn_deg)

    def update(
        self,
        path: np.ndarray,
        user_rc: np.ndarray,
        blocked: np.ndarray | None,
        cell_m: float,
        now: float,
    ) -> str:
        """``"go"`` (guide along ``path``), ``"hold"`` (say wait) or ``"expired"`` (detour now).

        ``path`` is the new grid path, ``user_rc`` the user's position in continuous cell units.
        """
        if not self.turns_around(path, user_rc, cell_m):
            self._clear_path, self._clear_at = path, now
            self.holding_until, self._spent = None, False
            return "go"
        if self.holding_until is not None:
            if now < self.holding_until:
                return "hold"
            self.holding_until, self._spent = None, True
            return "expired"
        if self.hold_s <= 0 or self._spent or blocked is None or self._clear_path is None:
            return "go"
        if now - self._clear_at > self.recent_s:
            return "go"
        ahead = self._block_distance_m(self._clear_path, user_rc, blocked, cell_m)
        if ahead is None or ahead < self.far_m:
            return "go"
        self.holding_until = now + self.hold_s
        self.holds += 1
        return "hold"

    @staticmethod
    def _block_distance_m(
        old: np.ndarray, user_rc: np.ndarray, blocked: np.ndarray, cell_m: float
    ) -> float | None:
        """Distance along the old path from the user to its first blocked cell (None: clear)."""
        if len(old) == 0:
            return None
        centres = old.astype(np.float64) + 0.5
        start = int(np.argmin(np.hypot(*(centres - user_rc).T)))
        rest = old[start:]
        hit = np.flatnonzero(blocked[rest[:, 0], rest[:, 1]])
        if hit.size == 0:
            return None
        seg = np.diff(centres[start : start + hit[0] + 1], axis=0)
        along = float(np.hypot(seg[:, 0], seg[:, 1]).sum())
        along += float(np.hypot(*(centres[start] - user_rc)))
        return along * cell_m


def _direction(path: np.ndarray, user_rc: np.ndarray, ahead_cells: float) -> float | None:
    """Direction (radians, grid frame) from the path point nearest the user to the point
    ``ahead_cells`` further along the path; None for a path too short to say."""
    if len(path) < 2:
        return None
    rc = np.ascontiguousarray(path, dtype=np.int64)
    angle = _direction_kernel(rc, np.asarray(user_rc, dtype=np.float64), float(ahead_cells))
    return None if math.isnan(angle) else angle


@njit(cache=True, nogil=True)
def _direction_kernel(path: np.ndarray, user_rc: np.ndarray, ahead_cells: float) -> float:
    """``_direction`` compiled (NaN: no direction); numpy's per-call overhead on a path of a
    few hundred cells was most of its cost."""
    n = path.shape[0]
    start, best = 0, np.inf
    for i in range(n):
        d = math.hypot(path[i, 0] + 0.5 - user_rc[0], path[i, 1] + 0.5 - user_rc[1])
        if d < best:
            start, best = i, d
    if start == n - 1:
        return np.nan
    # The first point whose distance along the path reaches ahead_cells (the last if none).
    along, k = 0.0, n - 1
    for i in range(start + 1, n):
        along += math.hypot(path[i, 0] - path[i - 1, 0], path[i, 1] - path[i - 1, 1])
        if along >= ahead_cells:
            k = i
            break
    dr, dc = float(path[k, 0] - path[start, 0]), float(path[k, 1] - path[start, 1])
    return math.atan2(-dr, dc)
